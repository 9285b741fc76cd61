"""The clock of an EMG amplifier against the controller's: offset and drift from sync events.

An amplifier and the controller host each count time with their own oscillator: they differ by an
offset (when each started counting) and a drift (crystal tolerances are tens of ppm, so 80 ppm is
~0.1 s over a 20-minute session, 200 times the 0.5 ms sample interval at 2 kHz). Every sync event
seen on both sides (a trigger edge, an LSL marker) gives one pair (recording time, controller time);
:func:`clock_fit` fits ``t_controller = offset + slope · t_recording`` by least squares over all of
them and reports the residuals, so a misplaced edge shows instead of silently bending the fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bowden.analysis.emg.constants import DRIFT_TOLERANCE_PPM as DRIFT_TOLERANCE_PPM
from bowden.analysis.emg.constants import POLARITIES as POLARITIES
from bowden.analysis.emg.constants import RESIDUAL_TOLERANCE_S as RESIDUAL_TOLERANCE_S
from bowden.analysis.emg.constants import TriggerPolarity as TriggerPolarity
from bowden.analysis.emg.signal import EmgSignal
from bowden.errors import ParameterError, SyncError

# The timing floor of an edge whose send took no measurable time (a GPIO write: microseconds; the
# recording's own sample grid then dominates): keeps the weights finite.
EDGE_FLOOR_S = 50e-6


@dataclass(frozen=True, kw_only=True)
class ClockFit:
    """``t_controller = offset_s + slope · t_recording``, fitted over ``n_events`` sync events.

    ``residuals_s`` are controller time minus the fit, one per event, in the order given;
    ``uncertainty_s`` how long each event's send took on the controller (the edge lies within it);
    ``drift_bound_ppm`` the largest drift those uncertainties alone could fake. A drift within that
    bound is not resolved by the events: the fit then keeps slope 1 (``drift_resolved`` False).
    """

    offset_s: float
    slope: float
    residuals_s: NDArray[np.float64]
    uncertainty_s: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    drift_bound_ppm: float = 0.0
    drift_resolved: bool = True

    @property
    def max_uncertainty_s(self) -> float:
        return float(np.max(self.uncertainty_s)) if self.uncertainty_s.size else 0.0

    @property
    def n_events(self) -> int:
        return int(self.residuals_s.size)

    @property
    def drift_ppm(self) -> float:
        """How much faster the recording's clock runs than the controller's, ppm."""
        return (1.0 / self.slope - 1.0) * 1e6

    @property
    def max_residual_s(self) -> float:
        return float(np.max(np.abs(self.residuals_s))) if self.residuals_s.size else 0.0

    @property
    def rms_residual_s(self) -> float:
        return float(np.sqrt(np.mean(self.residuals_s**2))) if self.residuals_s.size else 0.0

    def to_controller(self, recording_s: ArrayLike) -> NDArray[np.float64]:
        return np.asarray(self.offset_s + self.slope * np.asarray(recording_s, dtype=np.float64))

    def describe(self) -> str:
        drift = (
            f"drift {self.drift_ppm:+.1f} ppm"
            if self.drift_resolved
            else f"drift not resolved by the edges (±{self.drift_bound_ppm:.0f} ppm), taken as 0"
        )
        text = (
            f"{self.n_events} sync events, offset {self.offset_s:.6f} s, {drift}, "
            f"residuals rms {1e3 * self.rms_residual_s:.3f} ms, max {1e3 * self.max_residual_s:.3f} ms"
        )
        if self.max_uncertainty_s > RESIDUAL_TOLERANCE_S:
            text += (
                f"; edges sent within up to {1e3 * self.max_uncertainty_s:.0f} ms (a command trigger): "
                "aligned no better than that"
            )
        return text


def clock_fit(
    recording_s: ArrayLike,
    controller_s: ArrayLike,
    *,
    drift_tolerance_ppm: float = DRIFT_TOLERANCE_PPM,
    residual_tolerance_s: float = RESIDUAL_TOLERANCE_S,
    uncertainty_s: ArrayLike | None = None,
) -> ClockFit:
    """Weighted least-squares offset and drift from paired sync event times (s), checked.

    ``uncertainty_s`` (default 0) is how long each event's send took on the controller: its edge lies
    somewhere in that interval, uniformly as far as bowden knows (variance u²/12). Events weigh by the
    inverse of that variance plus :data:`EDGE_FLOOR_S`², so a GPIO edge outweighs a command's and
    events of equal uncertainty weigh equally (ordinary least squares). A residual may exceed
    ``residual_tolerance_s`` by half its event's uncertainty. The drift must exceed what the
    uncertainties alone could produce (the worst case of the weighted slope over edges anywhere in
    their intervals), else it is not resolved and the fit keeps slope 1 rather than report latency as
    drift. One event fixes the offset only. Times are centred before the fit, so sessions that start
    hours into either clock lose no precision.

    Raises
    ------
    SyncError
        No events, a drift beyond ``drift_tolerance_ppm``, or a residual beyond its tolerance (the
        message names the worst event).
    """
    if not (math.isfinite(drift_tolerance_ppm) and drift_tolerance_ppm > 0.0):
        raise ParameterError(f"--max-drift-ppm must be positive, got {drift_tolerance_ppm:g}")
    if not (math.isfinite(residual_tolerance_s) and residual_tolerance_s > 0.0):
        raise ParameterError(f"--max-residual-ms must be positive, got {1e3 * residual_tolerance_s:g}")
    x = np.asarray(recording_s, dtype=np.float64).ravel()
    y = np.asarray(controller_s, dtype=np.float64).ravel()
    u = np.zeros_like(x) if uncertainty_s is None else np.asarray(uncertainty_s, dtype=np.float64).ravel()
    if x.size != y.size or u.size != x.size:
        raise ParameterError(
            f"{x.size} recording times but {y.size} controller times, {u.size} uncertainties"
        )
    if x.size == 0:
        raise SyncError("no sync event is shared by the recording and the store")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise SyncError("a sync event time is not finite")
    u = np.where(np.isfinite(u) & (u > 0.0), u, 0.0)
    weights = 1.0 / (u**2 / 12.0 + EDGE_FLOOR_S**2)
    x0, y0 = float(np.average(x, weights=weights)), float(np.average(y, weights=weights))
    dx, dy = x - x0, y - y0
    spread = float(np.dot(weights * dx, dx))
    slope = float(np.dot(weights * dx, dy) / spread) if x.size > 1 and spread > 0.0 else 1.0
    # The slope's worst-case error were every edge at the far end of its interval (half of u).
    bound = float(np.dot(weights * np.abs(dx), 0.5 * u) / spread) if x.size > 1 and spread > 0.0 else 0.0
    resolved = abs(slope - 1.0) > bound or bound == 0.0
    if not resolved:  # latency could explain all of it: no drift, the weighted mean offset
        slope = 1.0
    offset = y0 - slope * x0
    fit = ClockFit(
        offset_s=offset,
        slope=slope,
        residuals_s=dy - slope * dx,
        uncertainty_s=u,
        drift_bound_ppm=1e6 * bound,
        drift_resolved=resolved,
    )
    if abs(fit.drift_ppm) > drift_tolerance_ppm:
        raise SyncError(
            f"the clocks drift {fit.drift_ppm:+.0f} ppm apart over {fit.n_events} sync events, beyond "
            f"the {drift_tolerance_ppm:g} ppm tolerance: events are mismatched or a clock is broken"
        )
    excess = np.abs(fit.residuals_s) - (residual_tolerance_s + 0.5 * u)
    if np.any(excess > 0.0):
        worst = int(np.argmax(excess))
        allowed = residual_tolerance_s + 0.5 * u[worst]
        raise SyncError(
            f"sync event {worst + 1} of {fit.n_events} (recording {x[worst]:.4f} s) is "
            f"{1e3 * fit.residuals_s[worst]:+.2f} ms off the fit, beyond {1e3 * allowed:g} ms "
            "(--max-residual-ms plus half the edge's send time): a spurious or shifted edge"
        )
    return fit


_MAX_TRIGGER_BIT = 31


def check_trigger_bit(bit: int) -> None:
    """Refuse a ``--trigger-bit`` outside the trigger word's bits (0–31)."""
    if not 0 <= bit <= _MAX_TRIGGER_BIT:
        raise ParameterError(f"--trigger-bit must be 0–{_MAX_TRIGGER_BIT}, got {bit}")


def trigger_pulses(
    emg: EmgSignal, channel: str, *, polarity: TriggerPolarity = "auto", bit: int | None = None
) -> NDArray[np.float64]:
    """A trigger channel's pulses (one per trial) as rows (leading, trailing edge), recording time, s.

    Edges are crossings of the midpoint between the channel's minimum and maximum, interpolated
    linearly between the two samples around it. A channel that never changes has no pulse.

    Parameters
    ----------
    polarity
        ``"high"``: the line idles low and a trial is a high pulse (bowden's GPIO line into a
        positive-logic input); ``"low"``: the line idles high and a trial is a low pulse (a
        negative-logic input such as the TMSi SAGA's TRIGGER port, whose bits read 1 while nothing
        drives them and 0 while a trigger does [TMSi knowledge base, "How can I send triggers to SAGA
        via USB ports?"]); ``"auto"``: from the baseline, the level at the recording's start and end.
    bit
        Read this bit (0 the least significant) of the channel's integer value instead of the whole
        value: a trigger word whose other bits are driven by other devices (the SAGA's TRIGGER port
        has 16 bits [TMSi knowledge base, "What are the specifications of SAGA's trigger inputs?"]).

    Raises
    ------
    SyncError
        The recording starts or ends inside a pulse (a trial cut in two), ``auto`` finds the line at
        different levels at the start and the end, or ``bit`` is asked of non-integer values.
    """
    if polarity not in POLARITIES:
        raise ParameterError(f"--trigger-polarity must be one of {', '.join(POLARITIES)}, got {polarity!r}")
    x = np.asarray(emg.channel(channel), dtype=np.float64)
    if bit is not None:
        x = _bit(x, channel, bit)
    low, high = float(np.min(x)), float(np.max(x))
    if not high > low:
        return np.empty((0, 2))
    level = 0.5 * (low + high)
    above = x >= level
    if polarity == "auto":
        if bool(above[0]) != bool(above[-1]):
            raise SyncError(
                f"trigger channel {channel!r} starts {'high' if above[0] else 'low'} and ends "
                f"{'high' if above[-1] else 'low'}: its idle level is unclear (a recording started or "
                "stopped inside a trial?); give --trigger-polarity high (the line idles low) or low "
                "(it idles high)"
            )
        polarity = "low" if above[0] else "high"
    if polarity == "low":  # a negative-logic line: a trial is a low pulse; mirror it
        x, level = -x, -level
        above = x >= level
    change = np.flatnonzero(above[1:] != above[:-1])
    fraction = (level - x[change]) / (x[change + 1] - x[change])
    times = emg.start_s + (change + fraction) / emg.rate_hz
    leading = above[change + 1]
    idle = "low" if polarity == "high" else "high"
    hint = (
        ""
        if polarity == "low"
        else "; if the input idles high (negative logic, e.g. a TMSi SAGA), give --trigger-polarity low"
    )
    if above[0]:
        raise SyncError(
            f"trigger channel {channel!r} is not {idle} when the recording starts (inside a trial){hint}"
        )
    if above[-1]:
        raise SyncError(
            f"trigger channel {channel!r} is still not {idle} when the recording ends (inside a trial)"
        )
    # Alternation is guaranteed by construction: idle at both ends, so edges lead, trail, lead...
    assert bool(np.all(leading[::2])) and not bool(np.any(leading[1::2]))
    return np.asarray(times.reshape(-1, 2), dtype=np.float64)


def _bit(values: NDArray[np.float64], channel: str, bit: int) -> NDArray[np.float64]:
    """Bit ``bit`` of a trigger word's values (0 or 1), which must be integers."""
    check_trigger_bit(bit)
    codes = np.rint(values)
    # An EDF export scales the word into its 16-bit range: a value within a quarter of an integer
    # is that integer; further off, the word's bits were not kept.
    if not (np.all(np.isfinite(values)) and np.all(np.abs(values - codes) <= 0.25)):
        raise SyncError(
            f"trigger channel {channel!r} does not hold integer values, so it has no bit {bit} to read "
            "(a trigger word exported without its codes?): leave out --trigger-bit"
        )
    return np.asarray((codes.astype(np.int64) >> bit) & 1, dtype=np.float64)


def match_pulses(
    pulses_s: ArrayLike,
    trials_s: ArrayLike,
    trial_ids: ArrayLike,
    *,
    drift_tolerance_ppm: float = DRIFT_TOLERANCE_PPM,
    residual_tolerance_s: float = RESIDUAL_TOLERANCE_S,
    uncertainty_s: ArrayLike | None = None,
) -> int:
    """Which consecutive trials a recording's trigger pulses belong to: the index of the first.

    ``pulses_s`` (recording clock) and ``trials_s`` (controller clock) are rows (start, end) in
    recording order. The pulses belong to trials ``k .. k + n - 1`` when every edge, timed from the
    first pulse's start, agrees with the trials' edges timed from trial ``k``'s start, within twice the
    residual tolerance plus the largest drift over that span (plus the edges' send times,
    ``uncertainty_s``, rows like ``trials_s``). Exactly one ``k`` must fit.

    Raises
    ------
    SyncError
        No pulse, more pulses than trials, no fit (naming the pulses and trials that could be
        matched, and the first pulse that matches none), or several fits.
    """
    pulses = np.asarray(pulses_s, dtype=np.float64).reshape(-1, 2)
    trials = np.asarray(trials_s, dtype=np.float64).reshape(-1, 2)
    spreads = np.zeros_like(trials)
    if uncertainty_s is not None:
        spreads = np.asarray(uncertainty_s, dtype=np.float64).reshape(-1, 2)
    ids = [int(i) for i in np.asarray(trial_ids).ravel()]
    n, m = len(pulses), len(trials)
    if n == 0:
        raise SyncError("the trigger channel holds no pulse: the recording covers no trial")
    if n > m:
        raise SyncError(
            f"the recording has {n} trigger pulses but the store has {m} trials with sync events "
            f"(trials {_ids(ids)}): {n - m} pulse(s) too many (if other devices drive the trigger "
            "channel's other bits, give --trigger-bit N)"
        )
    relative_pulses = pulses - pulses[0, 0]
    # A wide drift window finds the run; a line through it then decides (and clock_fit reports a
    # drift beyond the tolerance as such, rather than as pulses that match nothing).
    window_ppm = max(5.0 * drift_tolerance_ppm, 1000.0)
    best = (0, 0)  # (pulses matched from the first, -k): the most, then the earliest run
    fits: list[int] = []
    for k in range(m - n + 1):
        relative = trials[k : k + n] - trials[k, 0]
        slack = spreads[k : k + n] + spreads[k, 0]  # both ends of each difference may be off
        allowed = 2.0 * residual_tolerance_s + slack + window_ppm * 1e-6 * np.abs(relative)
        ok = np.all(np.abs(relative_pulses - relative) <= allowed, axis=1)
        matched = n if ok.all() else int(np.argmin(ok))
        best = max(best, (matched, -k))
        line_budget = 2.0 * residual_tolerance_s + float(np.max(spreads[k : k + n]))
        if ok.all() and _line_residual(pulses, trials[k : k + n]) <= line_budget:
            fits.append(k)
    if len(fits) == 1:
        return fits[0]
    if fits:
        options = "; ".join(f"trials {_ids(ids[k : k + n])}" for k in fits)
        raise SyncError(
            f"the {n} trigger pulses fit more than one run of trials ({options}): cannot tell which"
        )
    matched, k = best[0], -best[1]
    if matched == n:  # every edge within the window, but no line through them within the budget
        raise SyncError(_off_the_line(pulses, trials[k : k + n], ids[k : k + n], residual_tolerance_s))
    if matched == 0:
        raise SyncError(
            f"the recording's {n} trigger pulses match no run of the store's {m} trials with sync events "
            f"(trials {_ids(ids)})"
        )
    raise SyncError(
        f"the recording's {n} trigger pulses do not all match the store's trials: pulses 1–{matched} match "
        f"trials {_ids(ids[k : k + matched])}, pulse {matched + 1} (at {pulses[matched, 0]:.3f} s in the "
        f"recording) matches no trial (a missing or spurious edge)"
    )


def _line_residual(x: NDArray[np.float64], y: NDArray[np.float64]) -> float:
    """Largest residual of a least-squares line y = a + b·x through paired edges, s."""
    xs, ys = x.ravel(), y.ravel()
    if xs.size < 2:
        return 0.0
    slope, intercept = np.polyfit(xs - xs[0], ys - ys[0], 1)
    return float(np.max(np.abs(intercept + slope * (xs - xs[0]) - (ys - ys[0]))))


def _off_the_line(
    pulses: NDArray[np.float64], trials: NDArray[np.float64], ids: list[int], residual_tolerance_s: float
) -> str:
    """Why pulses that each fall near a trial's edges still fit no run: the edges off their common line."""
    xs, ys = pulses.ravel() - pulses[0, 0], trials.ravel() - trials[0, 0]
    slope, intercept = np.polyfit(xs, ys, 1)
    residuals = (ys - (intercept + slope * xs)).reshape(-1, 2)
    worst = np.abs(residuals).max(axis=1)
    off = [i for i in range(len(ids)) if worst[i] > 2.0 * residual_tolerance_s] or [int(np.argmax(worst))]
    edges = ", ".join(
        f"trial {ids[i]}'s {'start' if abs(residuals[i, 0]) >= abs(residuals[i, 1]) else 'end'} edge "
        f"{1e3 * residuals[i, np.argmax(np.abs(residuals[i]))]:+.1f} ms"
        for i in off
    )
    return (
        f"the recording's {len(ids)} trigger pulses fall near trials {_ids(ids)}, but their edges fit no "
        f"one clock: {edges} off the line through all edges, beyond twice --max-residual-ms "
        f"({2e3 * residual_tolerance_s:g} ms): a shifted edge, or a trigger too uncertain"
    )


def _ids(ids: list[int]) -> str:
    return ", ".join(str(i) for i in ids)
