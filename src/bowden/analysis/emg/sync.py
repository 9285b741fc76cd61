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
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bowden.analysis.emg.signal import EmgSignal
from bowden.errors import ParameterError, SyncError

# Defaults of the import: a crystal beyond 200 ppm is broken or the events are mismatched, and a
# residual beyond 2 ms (4 samples at 2 kHz) means an edge that is not where the controller sent it.
DRIFT_TOLERANCE_PPM = 200.0
RESIDUAL_TOLERANCE_S = 2e-3


@dataclass(frozen=True, kw_only=True)
class ClockFit:
    """``t_controller = offset_s + slope · t_recording``, fitted over ``n_events`` sync events.

    ``residuals_s`` are controller time minus the fit, one per event, in the order given.
    """

    offset_s: float
    slope: float
    residuals_s: NDArray[np.float64]

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
        return (
            f"{self.n_events} sync events, offset {self.offset_s:.6f} s, drift {self.drift_ppm:+.1f} ppm, "
            f"residuals rms {1e3 * self.rms_residual_s:.3f} ms, max {1e3 * self.max_residual_s:.3f} ms"
        )


def clock_fit(
    recording_s: ArrayLike,
    controller_s: ArrayLike,
    *,
    drift_tolerance_ppm: float = DRIFT_TOLERANCE_PPM,
    residual_tolerance_s: float = RESIDUAL_TOLERANCE_S,
) -> ClockFit:
    """Least-squares offset and drift from paired sync event times (s), checked against tolerances.

    One event fixes the offset only (slope 1). Times are centred before the fit, so sessions that
    start hours into either clock lose no precision.

    Raises
    ------
    SyncError
        No events, a drift beyond ``drift_tolerance_ppm``, or a residual beyond ``residual_tolerance_s``
        (the message names the worst event).
    """
    if not (math.isfinite(drift_tolerance_ppm) and drift_tolerance_ppm > 0.0):
        raise ParameterError(f"drift_tolerance_ppm must be positive, got {drift_tolerance_ppm}")
    if not (math.isfinite(residual_tolerance_s) and residual_tolerance_s > 0.0):
        raise ParameterError(f"residual_tolerance_s must be positive, got {residual_tolerance_s}")
    x = np.asarray(recording_s, dtype=np.float64).ravel()
    y = np.asarray(controller_s, dtype=np.float64).ravel()
    if x.size != y.size:
        raise ParameterError(f"{x.size} recording times but {y.size} controller times")
    if x.size == 0:
        raise SyncError("no sync event is shared by the recording and the store")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise SyncError("a sync event time is not finite")
    x0, y0 = float(np.mean(x)), float(np.mean(y))
    dx, dy = x - x0, y - y0
    spread = float(np.dot(dx, dx))
    slope = float(np.dot(dx, dy) / spread) if x.size > 1 and spread > 0.0 else 1.0
    offset = y0 - slope * x0
    fit = ClockFit(offset_s=offset, slope=slope, residuals_s=dy - slope * dx)
    if abs(fit.drift_ppm) > drift_tolerance_ppm:
        raise SyncError(
            f"the clocks drift {fit.drift_ppm:+.0f} ppm apart over {fit.n_events} sync events, beyond "
            f"the {drift_tolerance_ppm:g} ppm tolerance: events are mismatched or a clock is broken"
        )
    if fit.max_residual_s > residual_tolerance_s:
        worst = int(np.argmax(np.abs(fit.residuals_s)))
        raise SyncError(
            f"sync event {worst + 1} of {fit.n_events} (recording {x[worst]:.4f} s) is "
            f"{1e3 * fit.residuals_s[worst]:+.2f} ms off the fit, beyond {1e3 * residual_tolerance_s:g} ms: "
            "a spurious or shifted edge"
        )
    return fit


def trigger_pulses(emg: EmgSignal, channel: str) -> NDArray[np.float64]:
    """The high pulses of a trigger channel as rows (rising, falling), recording time, s.

    Edges are crossings of the midpoint between the channel's minimum and maximum, interpolated
    linearly between the two samples around it. A channel that never changes has no pulse.

    Raises
    ------
    SyncError
        If the recording starts or ends while the line is high (a trial cut in two).
    """
    x = np.asarray(emg.channel(channel))
    low, high = float(np.min(x)), float(np.max(x))
    if not high > low:
        return np.empty((0, 2))
    level = 0.5 * (low + high)
    above = x >= level
    change = np.flatnonzero(above[1:] != above[:-1])
    fraction = (level - x[change]) / (x[change + 1] - x[change])
    times = emg.start_s + (change + fraction) / emg.rate_hz
    rising = above[change + 1]
    if above[0]:
        raise SyncError(f"trigger channel {channel!r} is high when the recording starts (inside a trial)")
    if above[-1]:
        raise SyncError(f"trigger channel {channel!r} is still high when the recording ends (inside a trial)")
    # Alternation is guaranteed by construction: low at both ends, so edges go up, down, up, down...
    assert bool(np.all(rising[::2])) and not bool(np.any(rising[1::2]))
    return np.asarray(times.reshape(-1, 2), dtype=np.float64)


def match_pulses(
    pulses_s: ArrayLike,
    trials_s: ArrayLike,
    trial_ids: ArrayLike,
    *,
    drift_tolerance_ppm: float = DRIFT_TOLERANCE_PPM,
    residual_tolerance_s: float = RESIDUAL_TOLERANCE_S,
) -> int:
    """Which consecutive trials a recording's trigger pulses belong to: the index of the first.

    ``pulses_s`` (recording clock) and ``trials_s`` (controller clock) are rows (start, end) in
    recording order. The pulses belong to trials ``k .. k + n - 1`` when every edge, timed from the
    first pulse's start, agrees with the trials' edges timed from trial ``k``'s start, within twice the
    residual tolerance plus the largest drift over that span. Exactly one ``k`` must fit.

    Raises
    ------
    SyncError
        No pulse, more pulses than trials, no fit (naming the pulses and trials that could be
        matched, and the first pulse that matches none), or several fits.
    """
    pulses = np.asarray(pulses_s, dtype=np.float64).reshape(-1, 2)
    trials = np.asarray(trials_s, dtype=np.float64).reshape(-1, 2)
    ids = [int(i) for i in np.asarray(trial_ids).ravel()]
    n, m = len(pulses), len(trials)
    if n == 0:
        raise SyncError("the trigger channel holds no pulse: the recording covers no trial")
    if n > m:
        raise SyncError(
            f"the recording has {n} trigger pulses but the store has {m} trials with sync events "
            f"(trials {_ids(ids)}): {n - m} pulse(s) too many"
        )
    relative_pulses = pulses - pulses[0, 0]
    # A wide drift window finds the run; a line through it then decides (and clock_fit reports a
    # drift beyond the tolerance as such, rather than as pulses that match nothing).
    window_ppm = max(5.0 * drift_tolerance_ppm, 1000.0)
    best = (0, 0)  # (pulses matched from the first, -k): the most, then the earliest run
    fits: list[int] = []
    for k in range(m - n + 1):
        relative = trials[k : k + n] - trials[k, 0]
        allowed = 2.0 * residual_tolerance_s + window_ppm * 1e-6 * np.abs(relative)
        ok = np.all(np.abs(relative_pulses - relative) <= allowed, axis=1)
        matched = n if ok.all() else int(np.argmin(ok))
        best = max(best, (matched, -k))
        if ok.all() and _line_residual(pulses, trials[k : k + n]) <= 2.0 * residual_tolerance_s:
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
