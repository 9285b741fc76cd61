"""Repetitions and their raising/lowering phases, and resampling onto normalised time.

A trial is ten raise-and-lower cycles between 20° and 100° (paper, "Protocol"). A repetition runs
from the low point before a rise to the low point after the following descent; its turning point
(the highest point) splits it into the raising and the lowering phase. Repetitions are found on the
reference elevation shown to the participant, which is noise-free and defines the task; when a
recording has no usable reference the measured elevation, low-pass filtered, is the fallback.
Crossings of 35 % and 65 % of the elevation range (a Schmitt trigger) locate each cycle without
being fooled by tremor near one level. The first repetition of each trial is dropped (paper: because
of adaptation when condition or speed change; Emken et al. 2007).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray
from scipy import signal as sps

from bowden.analysis.emg.signal import rate_from_time
from bowden.contracts import (
    REPETITIONS_PER_TRIAL,
    TRIAL_ELEVATION,
    TRIAL_REFERENCE_ELEVATION,
    TRIAL_TIME,
)
from bowden.errors import ParameterError, RecordingError

SegmentationSource = Literal["auto", "reference", "elevation"]
_LOW_FRACTION = 0.35
_HIGH_FRACTION = 0.65
# Samples within this fraction of the range count as the same extreme (a held plateau). It must be
# tiny: a minimum-jerk profile is so flat near its ends (x ∝ τ³) that a looser tolerance would move
# the start of a movement by tens of milliseconds.
_PLATEAU_TOLERANCE = 1e-9
# Fewest samples a complete low → high → low cycle can have: low, high, low, and one more sample
# that shows the descent has ended (a cycle still falling at the last sample is incomplete).
MIN_CYCLE_SAMPLES = 4


@dataclass(frozen=True, kw_only=True)
class SegmentationParameters:
    """Settings of :func:`segment_repetitions`.

    Parameters
    ----------
    source
        ``"reference"``, ``"elevation"`` (measured), or ``"auto"``: the reference when the trial has
        a finite reference column, else the measured elevation.
    expected_repetitions
        Complete repetitions a trial must contain (paper: 10); ``None`` accepts any number ≥ 1.
    drop_first
        Repetitions dropped from the start of each trial (paper: 1).
    elevation_lowpass_hz
        Zero-phase low-pass (2nd-order Butterworth) applied to the measured elevation before it is
        segmented, Hz. The reference is used as recorded.
    n_points
        Samples of the normalised time grid 0…1 (1001: steps of 0.1 % of the cycle).
    """

    source: SegmentationSource = "auto"
    expected_repetitions: int | None = REPETITIONS_PER_TRIAL
    drop_first: int = 1
    elevation_lowpass_hz: float = 5.0
    n_points: int = 1001

    def __post_init__(self) -> None:
        if self.source not in ("auto", "reference", "elevation"):
            raise ParameterError(f"source must be 'auto', 'reference' or 'elevation', got {self.source!r}")
        if self.expected_repetitions is not None and not (
            isinstance(self.expected_repetitions, int) and self.expected_repetitions >= 1
        ):
            raise ParameterError(
                f"expected_repetitions must be a positive integer or None, got {self.expected_repetitions!r}"
            )
        if not (isinstance(self.drop_first, int) and self.drop_first >= 0):
            raise ParameterError(f"drop_first must be a non-negative integer, got {self.drop_first!r}")
        if self.expected_repetitions is not None and self.drop_first >= self.expected_repetitions:
            raise ParameterError("drop_first must be smaller than expected_repetitions")
        if not (math.isfinite(self.elevation_lowpass_hz) and self.elevation_lowpass_hz > 0.0):
            raise ParameterError(f"elevation_lowpass_hz must be positive, got {self.elevation_lowpass_hz}")
        if not (isinstance(self.n_points, int) and self.n_points >= 3):
            raise ParameterError(f"n_points must be an integer ≥ 3, got {self.n_points!r}")


@dataclass(frozen=True, kw_only=True)
class Repetition:
    """One raise-and-lower cycle on the controller's time base.

    ``number`` counts complete repetitions in the trial from 1 (the dropped first one included).
    """

    number: int
    start_s: float
    turn_s: float
    end_s: float

    @property
    def duration_s(self) -> float:
        """Length of the cycle, s."""
        return self.end_s - self.start_s

    @property
    def turn_fraction(self) -> float:
        """Normalised time (0…1) of the turning point: end of raising, start of lowering."""
        return (self.turn_s - self.start_s) / (self.end_s - self.start_s)


@dataclass(frozen=True, kw_only=True)
class Segmentation:
    """Repetitions kept for analysis, and how they were found."""

    repetitions: tuple[Repetition, ...]
    source: Literal["reference", "elevation"]
    n_found: int
    n_dropped: int


def segment_repetitions(
    trial: pd.DataFrame, parameters: SegmentationParameters | None = None
) -> Segmentation:
    """Find the repetitions of a trial recording (columns of ``bowden.contracts.TRIAL_*``).

    Raises :class:`~bowden.errors.RecordingError` when the time or elevation columns are missing or
    unusable, or when the number of complete repetitions differs from ``expected_repetitions``.
    """
    params = parameters or SegmentationParameters()
    if TRIAL_TIME not in trial.columns:
        raise RecordingError(f"trial recording has no {TRIAL_TIME!r} column")
    time = np.asarray(trial[TRIAL_TIME], dtype=np.float64)
    source, elevation = _segmentation_signal(trial, time, params)
    found = find_cycles(time, elevation)
    if params.expected_repetitions is not None and len(found) != params.expected_repetitions:
        raise RecordingError(
            f"found {len(found)} complete repetitions in the {source} column "
            f"({TRIAL_REFERENCE_ELEVATION if source == 'reference' else TRIAL_ELEVATION!r}), expected "
            f"{params.expected_repetitions}; pass expected_repetitions=None to accept a partial trial"
        )
    if len(found) <= params.drop_first:
        raise RecordingError(
            f"found {len(found)} complete repetitions, none left after dropping the first {params.drop_first}"
        )
    return Segmentation(
        repetitions=tuple(found[params.drop_first :]),
        source=source,
        n_found=len(found),
        n_dropped=params.drop_first,
    )


def find_cycles(time_s: ArrayLike, elevation: ArrayLike) -> list[Repetition]:
    """Complete low → high → low cycles of an elevation trace (any unit), in time order.

    Raises :class:`~bowden.errors.RecordingError` when the trace is empty or too short to hold a
    cycle (fewer than :data:`MIN_CYCLE_SAMPLES` samples), when time and elevation differ in length,
    when the elevation is not finite (naming the row), or when it does not move.
    """
    t = np.asarray(time_s, dtype=np.float64).reshape(-1)
    x = np.asarray(elevation, dtype=np.float64).reshape(-1)
    if t.size != x.size:
        raise RecordingError(f"time has {t.size} samples but elevation has {x.size}")
    if x.size < MIN_CYCLE_SAMPLES:
        # An empty trial (a run stopped before its first cycle) must say so, not fail inside numpy.
        what = "no samples" if x.size == 0 else f"only {x.size} sample{'s' if x.size > 1 else ''}"
        raise RecordingError(
            f"the trial has {what}: too short to hold a repetition "
            f"(at least {MIN_CYCLE_SAMPLES} are needed)"
        )
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        raise RecordingError(f"elevation is not finite at row {int(bad[0])}: cannot find repetitions")
    low, high = float(np.min(x)), float(np.max(x))
    span = high - low
    if not span > 0.0:
        raise RecordingError("elevation does not move: no repetitions to find")
    upper = low + _HIGH_FRACTION * span
    lower = low + _LOW_FRACTION * span
    tolerance = _PLATEAU_TOLERANCE * span
    rises, falls = _schmitt_events(x, lower, upper)
    cycles: list[Repetition] = []
    for i, rise in enumerate(rises):
        previous_fall = max((f for f in falls if f < rise), default=0)
        next_fall = min((f for f in falls if f > rise), default=None)
        if next_fall is None:
            break
        next_rise = rises[i + 1] if i + 1 < len(rises) else x.size
        # Look for the low points no further than 1.5 half-cycles away, so that a rest before the
        # first or after the last repetition (arm dropped further) is not taken for part of it.
        reach = int(1.5 * (next_fall - rise)) + 1
        previous_fall = max(previous_fall, rise - reach)
        next_rise = min(next_rise, next_fall + reach)
        before = x[previous_fall : rise + 1]
        after = x[next_fall:next_rise]
        if before.min() >= lower or after.min() >= lower:
            continue  # the cycle is cut by the start or the end of the record
        start = previous_fall + int(np.flatnonzero(before <= before.min() + tolerance)[-1])
        end = next_fall + int(np.flatnonzero(after <= after.min() + tolerance)[0])
        if end == x.size - 1 and x[end - 1] - x[end] > tolerance:
            continue  # still descending when the record stops: the cycle is incomplete
        top = x[rise : next_fall + 1]
        plateau = rise + np.flatnonzero(top >= top.max() - tolerance)
        turn = 0.5 * (t[plateau[0]] + t[plateau[-1]])
        cycles.append(
            Repetition(
                number=len(cycles) + 1, start_s=float(t[start]), turn_s=float(turn), end_s=float(t[end])
            )
        )
    return cycles


def normalised_time(n_points: int) -> NDArray[np.float64]:
    """The normalised time grid 0…1 of a repetition."""
    return np.linspace(0.0, 1.0, n_points)


def resample_repetition(
    time_s: ArrayLike, values: ArrayLike, repetition: Repetition, n_points: int
) -> NDArray[np.float64]:
    """Linear interpolation of ``values`` (samples x ...) at the normalised-time grid of a repetition."""
    t = np.asarray(time_s, dtype=np.float64)
    y = np.asarray(values, dtype=np.float64)
    grid = repetition.start_s + normalised_time(n_points) * repetition.duration_s
    if grid[0] < t[0] - 1e-9 or grid[-1] > t[-1] + 1e-9:
        raise RecordingError(
            f"repetition {repetition.number} ({repetition.start_s:.3f}–{repetition.end_s:.3f} s) lies "
            f"outside the signal ({t[0]:.3f}–{t[-1]:.3f} s)"
        )
    if y.ndim == 1:
        return np.interp(grid, t, y)
    return np.column_stack([np.interp(grid, t, y[:, j]) for j in range(y.shape[1])])


def _segmentation_signal(
    trial: pd.DataFrame, time: NDArray[np.float64], params: SegmentationParameters
) -> tuple[Literal["reference", "elevation"], NDArray[np.float64]]:
    has_reference = TRIAL_REFERENCE_ELEVATION in trial.columns and bool(
        np.all(np.isfinite(np.asarray(trial[TRIAL_REFERENCE_ELEVATION], dtype=np.float64)))
    )
    if params.source == "reference" or (params.source == "auto" and has_reference):
        if not has_reference:
            raise RecordingError(
                f"column {TRIAL_REFERENCE_ELEVATION!r} is missing or not finite; use source='elevation'"
            )
        return "reference", np.asarray(trial[TRIAL_REFERENCE_ELEVATION], dtype=np.float64)
    if TRIAL_ELEVATION not in trial.columns:
        raise RecordingError(
            f"trial recording has neither {TRIAL_REFERENCE_ELEVATION!r} nor {TRIAL_ELEVATION!r}"
        )
    elevation = np.asarray(trial[TRIAL_ELEVATION], dtype=np.float64)
    bad = np.flatnonzero(~np.isfinite(elevation))
    if bad.size:
        raise RecordingError(f"column {TRIAL_ELEVATION!r} is not finite at row {int(bad[0])}")
    rate = rate_from_time(time, what=f"trial column {TRIAL_TIME!r}")
    if params.elevation_lowpass_hz < rate / 2.0 and elevation.size > 15:
        sos = sps.butter(2, params.elevation_lowpass_hz, btype="lowpass", fs=rate, output="sos")
        elevation = sps.sosfiltfilt(sos, elevation)
    return "elevation", elevation


def _schmitt_events(x: NDArray[np.float64], lower: float, upper: float) -> tuple[list[int], list[int]]:
    """Indices where x first exceeds ``upper`` after being below ``lower`` (rises) and vice versa."""
    rises: list[int] = []
    falls: list[int] = []
    above = np.flatnonzero(x > upper)
    below = np.flatnonzero(x < lower)
    state_high = bool(x[0] > upper)
    position = 0
    while True:
        candidates = below if state_high else above
        k = int(np.searchsorted(candidates, position))
        if k >= candidates.size:
            break
        position = int(candidates[k])
        (falls if state_high else rises).append(position)
        state_high = not state_high
    return rises, falls
