"""Preprocessing of a bench recording as the paper's "Model identification" section describes it.

1. Split the recording into continuous segments: a new segment starts at every trial (and file)
   boundary and wherever the time step exceeds ``gap_factor`` times the segment's median step.
2. Low-pass load-cell tension, motor torque and spool velocity with a zero-phase (forward-backward)
   third-order Butterworth filter at 5 Hz, segment by segment, so that no filter ever runs across a
   gap or from one trial into the next.
3. Spool acceleration is the derivative of the filtered velocity (second-order central differences).
4. Keep steady-state samples: |speed| > 15 °/s, |acceleration| < 15 °/s², 20° < elevation < 90°,
   torque > 0 (the paper's "TDU_acc < 15 °/s" is read as |acceleration| < 15 °/s², our reading of the
   paper's "Model identification").
5. Split them by the sign of the filtered spool velocity: > 0 raising (cable reeled in), < 0 lowering.

Every threshold is a field of :class:`PreprocessSettings`. The forward-backward filter squares the
Butterworth magnitude, so the effective cutoff (−6 dB) is at ``cutoff_hz``; edges are handled by
SciPy's odd-extension padding (MATLAB's ``filtfilt`` pads slightly differently, which only affects
the first and last few samples of a segment, all of which the acceleration criterion usually drops).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import scipy.signal
from numpy.typing import NDArray

from bowden.errors import ParameterError, RecordingError
from bowden.identify.recording import BenchRecording

# Defined in the light settings module (the command line's parser reads them); re-exported here.
from bowden.identify.settings import DIRECTIONS as DIRECTIONS
from bowden.identify.settings import LOWERING as LOWERING
from bowden.identify.settings import RAISING as RAISING
from bowden.identify.settings import PreprocessSettings as PreprocessSettings


@dataclass(frozen=True, eq=False)
class FilteredBench:
    """A bench recording cut into continuous segments and low-passed segment by segment.

    ``segment`` is −1 for samples of segments too short to filter; their filtered values are NaN.
    ``segment_rate_hz[i]`` is the sampling rate (1 / median step) of segment i.
    """

    recording: BenchRecording
    segment: NDArray[np.int64]
    segment_rate_hz: tuple[float, ...]
    tension_n: NDArray[np.float64]
    motor_torque_nm: NDArray[np.float64]
    motor_velocity_rad_s: NDArray[np.float64]
    motor_acceleration_rad_s2: NDArray[np.float64]

    @property
    def elevation_rad(self) -> NDArray[np.float64]:
        """Elevation is used for selection only and is not filtered (as in the paper)."""
        return self.recording.elevation_rad

    @property
    def n_segments(self) -> int:
        return len(self.segment_rate_hz)

    @property
    def n_unfiltered(self) -> int:
        """Samples dropped because their segment was too short for the filter."""
        return int(np.count_nonzero(self.segment < 0))


@dataclass(frozen=True, eq=False)
class SteadyStateSelection:
    """Which filtered samples are steady state, per criterion and overall, split by direction."""

    filtered: FilteredBench
    settings: PreprocessSettings
    criteria: dict[str, NDArray[np.bool_]]
    selected: NDArray[np.bool_]
    raising: NDArray[np.bool_]
    lowering: NDArray[np.bool_]

    def direction_mask(self, direction: str) -> NDArray[np.bool_]:
        if direction == RAISING:
            return self.raising
        if direction == LOWERING:
            return self.lowering
        raise ParameterError(f"direction must be {RAISING!r} or {LOWERING!r}, got {direction!r}")

    def tension_n(self, direction: str) -> NDArray[np.float64]:
        """Filtered load-cell tension of the selected samples of one direction, N."""
        return self.filtered.tension_n[self.direction_mask(direction)]

    def motor_torque_nm(self, direction: str) -> NDArray[np.float64]:
        """Filtered motor torque of the selected samples of one direction, Nm."""
        return self.filtered.motor_torque_nm[self.direction_mask(direction)]

    def count(self, direction: str) -> int:
        return int(np.count_nonzero(self.direction_mask(direction)))

    def rejection_report(self, direction: str) -> str:
        """How many samples moving in ``direction`` each criterion rejects (for error messages)."""
        velocity = self.filtered.motor_velocity_rad_s
        moving = (velocity > 0.0) if direction == RAISING else (velocity < 0.0)
        labels = self.settings.criterion_labels()
        parts = [
            f"{int(np.count_nonzero(moving & ~passes))} fail {labels[name]}"
            for name, passes in self.criteria.items()
            if name != "speed"
        ]
        total = int(np.count_nonzero(moving))
        speed = int(np.count_nonzero(moving & ~self.criteria["speed"]))
        return f"of {total} samples moving {direction}, {speed} fail {labels['speed']}, " + ", ".join(parts)


def _segment_bounds(
    time_s: NDArray[np.float64], block: NDArray[np.int64], gap_factor: float
) -> list[tuple[int, int, float]]:
    """(start, stop, median step) of each continuous segment; stop is exclusive."""
    segments: list[tuple[int, int, float]] = []
    block_starts = np.flatnonzero(np.diff(block)) + 1
    edges = np.concatenate([[0], block_starts, [time_s.shape[0]]])
    for start, stop in itertools.pairwise(edges):
        if stop - start < 2:
            segments.append((int(start), int(stop), math.nan))
            continue
        steps = np.diff(time_s[start:stop])
        median_step = float(np.median(steps))
        cuts = np.flatnonzero(steps > gap_factor * median_step) + 1 + start
        piece_edges = np.concatenate([[start], cuts, [stop]])
        for a, b in itertools.pairwise(piece_edges):
            piece_step = float(np.median(np.diff(time_s[a:b]))) if b - a >= 2 else math.nan
            segments.append((int(a), int(b), piece_step))
    return segments


def bench_filter(recording: BenchRecording, settings: PreprocessSettings | None = None) -> FilteredBench:
    """Cut ``recording`` into continuous segments and low-pass each one (zero phase).

    Raises
    ------
    RecordingError
        When a segment's sampling rate is too low for the cutoff (names the segment's first row).
    """
    settings = settings or PreprocessSettings()
    n = recording.n_samples
    segment = np.full(n, -1, dtype=np.int64)
    tension = np.full(n, np.nan)
    torque = np.full(n, np.nan)
    velocity = np.full(n, np.nan)
    acceleration = np.full(n, np.nan)
    rates: list[float] = []
    designs: dict[float, NDArray[np.float64]] = {}
    for start, stop, step in _segment_bounds(recording.time_s, recording.block, settings.gap_factor):
        if not math.isfinite(step):
            continue
        rate_hz = 1.0 / step
        if settings.cutoff_hz >= 0.5 * rate_hz:
            raise RecordingError(
                f"the segment starting at {recording.describe_sample(start)} is sampled at "
                f"{rate_hz:.3g} Hz, too slow for a {settings.cutoff_hz:g} Hz low-pass "
                f"(the cutoff must stay below half the sampling rate)"
            )
        # One filter design per distinct rate (rounded so jitter does not defeat the cache).
        key = round(rate_hz, 6)
        sos = designs.get(key)
        if sos is None:
            sos = scipy.signal.butter(settings.filter_order, settings.cutoff_hz, fs=rate_hz, output="sos")
            designs[key] = sos
        pad = 3 * (2 * sos.shape[0] + 1)
        if stop - start <= pad:
            continue  # too short to filter: left at NaN and segment −1
        index = len(rates)
        rates.append(rate_hz)
        window = slice(start, stop)
        segment[window] = index
        tension[window] = scipy.signal.sosfiltfilt(sos, recording.tension_n[window])
        torque[window] = scipy.signal.sosfiltfilt(sos, recording.motor_torque_nm[window])
        velocity[window] = scipy.signal.sosfiltfilt(sos, recording.motor_velocity_rad_s[window])
        acceleration[window] = np.gradient(velocity[window], recording.time_s[window])
    return FilteredBench(
        recording=recording,
        segment=segment,
        segment_rate_hz=tuple(rates),
        tension_n=tension,
        motor_torque_nm=torque,
        motor_velocity_rad_s=velocity,
        motor_acceleration_rad_s2=acceleration,
    )


def bench_select(filtered: FilteredBench, settings: PreprocessSettings | None = None) -> SteadyStateSelection:
    """Apply the steady-state criteria and split the kept samples by spool velocity sign."""
    settings = settings or PreprocessSettings()
    valid = filtered.segment >= 0
    with np.errstate(invalid="ignore"):
        velocity = filtered.motor_velocity_rad_s
        elevation = filtered.elevation_rad
        criteria = {
            "speed": valid & (np.abs(velocity) > settings.min_speed_rad_s),
            "acceleration": valid
            & (np.abs(filtered.motor_acceleration_rad_s2) < settings.max_abs_acceleration_rad_s2),
            "elevation": (elevation > settings.min_elevation_rad) & (elevation < settings.max_elevation_rad),
            "torque": valid & (filtered.motor_torque_nm > settings.min_torque_nm),
        }
        selected = np.logical_and.reduce(list(criteria.values()))
        raising = selected & (velocity > 0.0)
        lowering = selected & (velocity < 0.0)
    return SteadyStateSelection(
        filtered=filtered,
        settings=settings,
        criteria=criteria,
        selected=selected,
        raising=raising,
        lowering=lowering,
    )


def bench_preprocess(
    recording: BenchRecording, settings: PreprocessSettings | None = None
) -> SteadyStateSelection:
    """Filter and select in one call: :func:`bench_filter` then :func:`bench_select`."""
    settings = settings or PreprocessSettings()
    return bench_select(bench_filter(recording, settings), settings)
