"""One trial → its outcome measures per repetition and phase, its curves and its EMG peaks.

:func:`analyse_trial` takes a trial DataFrame with the ``bowden.contracts`` ``TRIAL_*`` columns and,
optionally, its raw EMG (``time_s`` on the controller time base, one column per muscle at 2 kHz),
and returns a :class:`TrialOutcomes`. What needs the other trials of the study (normalisation to the
no-suit peaks, iEMG, mean ± SD curves) is :mod:`bowden.analysis.outcomes`'s job.

Measures, per kept repetition and phase (``entire``, ``raising``, ``lowering``):

* ``tension_rmse_n`` — RMSE of measured vs desired cable tension;
* ``torque_rmse_nm`` — the same for the joint torque, tension × ``moment_arm_m``;
* ``percent_error_rmse_pct`` — RMSE of the per-sample percent error (identical for tension and
  torque); samples whose desired tension is ≤ ``min_reference_tension_n`` are left out;
* ``peak_percent_error_pct`` and ``peak_percent_error_time_pct`` — signed percent error of largest
  magnitude and where it occurs, in % of the repetition's normalised time (raising, lowering);
* ``elevation_rmse_rad`` — RMSE of measured vs reference elevation;
* ``sparc`` — SPARC of the elevation *speed* |θ̇| (the ``elevation_velocity_rad_s`` column from
  the IMU), for the whole repetition and for each phase: a phase is one discrete movement, for which
  SPARC was designed; the entire cycle (two bells) is what the paper's values (≈ −2.4…−2.8) suggest.

Error measures use the recorded samples inside each phase; curves use the normalised grid.
Tension measures are omitted for trials without load-cell data (e.g. no suit).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from bowden.analysis.emg.normalize import emg_mean_peak
from bowden.analysis.emg.process import EmgProcessParameters, emg_pipeline
from bowden.analysis.emg.signal import EmgSignal
from bowden.analysis.metrics import percent_error, rmse, root_mean_square, signed_peak
from bowden.analysis.segmentation import (
    Repetition,
    SegmentationParameters,
    resample_repetition,
    segment_repetitions,
)
from bowden.analysis.sparc import SparcParameters, sparc
from bowden.contracts import (
    CONDITIONS,
    MUSCLES,
    PROTOCOL_NAME_RULE,
    SPEEDS,
    TRIAL_DESIRED_TENSION,
    TRIAL_ELEVATION,
    TRIAL_ELEVATION_VELOCITY,
    TRIAL_MOMENT_ARM,
    TRIAL_REFERENCE_ELEVATION,
    TRIAL_TENSION,
    TRIAL_TIME,
    is_protocol_name,
)
from bowden.errors import ParameterError, RecordingError

OUTCOME_COLUMNS = ("participant", "condition", "speed", "repetition", "phase", "measure", "value")
TENSION_RMSE = "tension_rmse_n"
TORQUE_RMSE = "torque_rmse_nm"
PERCENT_ERROR_RMSE = "percent_error_rmse_pct"
PEAK_PERCENT_ERROR = "peak_percent_error_pct"
PEAK_PERCENT_ERROR_TIME = "peak_percent_error_time_pct"
ELEVATION_RMSE = "elevation_rmse_rad"
SPARC = "sparc"
IEMG_PREFIX = "iemg_"
# Physical signals resampled onto normalised time, in this order.
CURVE_SIGNALS = (
    "reference_elevation_rad",
    "elevation_rad",
    "desired_tension_n",
    "tension_n",
    "desired_torque_nm",
    "torque_nm",
)
_REQUIRED = (
    TRIAL_TIME,
    TRIAL_REFERENCE_ELEVATION,
    TRIAL_ELEVATION,
    TRIAL_ELEVATION_VELOCITY,
    TRIAL_DESIRED_TENSION,
    TRIAL_MOMENT_ARM,
    TRIAL_TENSION,
)


@dataclass(frozen=True, kw_only=True)
class TrialMetadata:
    """Who, in which condition and at which speed (``bowden.contracts`` names)."""

    participant: str
    condition: str
    speed: str

    def __post_init__(self) -> None:
        if not (isinstance(self.participant, str) and self.participant):
            raise ParameterError(f"participant must be a non-empty string, got {self.participant!r}")
        # The paper's names, or a lab's own by the one rule (bowden.protocol.catalogue).
        if self.condition not in CONDITIONS and not is_protocol_name(self.condition):
            raise ParameterError(f"condition must be one of {CONDITIONS} or {PROTOCOL_NAME_RULE}, "
                                 f"got {self.condition!r}")
        if self.speed not in SPEEDS and not is_protocol_name(self.speed):
            raise ParameterError(f"speed must be one of {SPEEDS} or {PROTOCOL_NAME_RULE}, got {self.speed!r}")

    @classmethod
    def coerce(cls, value: TrialMetadata | Mapping[str, Any]) -> TrialMetadata:
        """Accept a TrialMetadata or a mapping with participant, condition and speed."""
        if isinstance(value, TrialMetadata):
            return value
        try:
            return cls(
                participant=str(value["participant"]), condition=value["condition"], speed=value["speed"]
            )
        except KeyError as exc:
            raise ParameterError(f"trial metadata lacks {exc.args[0]!r}") from None


@dataclass(frozen=True, kw_only=True)
class AnalysisParameters:
    """Everything :func:`analyse_study` does, in one validated object (defaults: the paper)."""

    emg: EmgProcessParameters = field(default_factory=EmgProcessParameters)
    segmentation: SegmentationParameters = field(default_factory=SegmentationParameters)
    sparc: SparcParameters = field(default_factory=SparcParameters)
    min_reference_tension_n: float = 1.0
    curve_points: int = 101

    def __post_init__(self) -> None:
        if not (math.isfinite(self.min_reference_tension_n) and self.min_reference_tension_n >= 0.0):
            raise ParameterError(f"min_reference_tension_n must be ≥ 0, got {self.min_reference_tension_n}")
        if not (isinstance(self.curve_points, int) and self.curve_points >= 2):
            raise ParameterError(f"curve_points must be an integer ≥ 2, got {self.curve_points!r}")


@dataclass
class TrialOutcomes:
    """What :func:`analyse_trial` found in one trial.

    Attributes
    ----------
    metadata
        Who, condition, speed.
    rows
        Outcome rows in ``OUTCOME_COLUMNS`` order (all measures but iEMG).
    repetitions
        The kept repetitions.
    curves
        Repetitions x normalised-time points x ``CURVE_SIGNALS``.
    emg_curves
        Repetitions x points x ``emg_channels`` envelope, V; ``None`` without EMG.
    emg_peaks
        Mean per-repetition envelope peak per channel, V; ``None`` without EMG.
    emg_channels
        EMG channels, in ``emg_curves`` order.
    segmentation_source
        What the repetitions were found on (``"reference"`` or ``"elevation"``).
    heart_rate_bpm
        Channel → mean heart rate found by the ECG removal, 1/min.
    """

    metadata: TrialMetadata
    rows: list[tuple[str, str, str, int, str, str, float]]
    repetitions: tuple[Repetition, ...]
    curves: NDArray[np.float64]
    emg_curves: NDArray[np.float64] | None
    emg_peaks: dict[str, float] | None
    emg_channels: tuple[str, ...]
    segmentation_source: str
    heart_rate_bpm: dict[str, float]


def analyse_trial(
    metadata: TrialMetadata,
    recording: pd.DataFrame,
    emg: pd.DataFrame | None = None,
    parameters: AnalysisParameters | None = None,
) -> TrialOutcomes:
    """Segment one trial and compute its outcome measures (module docstring) and curves.

    Raises :class:`~bowden.errors.RecordingError` naming the trial when a column is missing or the
    recording cannot be segmented or processed.
    """
    params = parameters or AnalysisParameters()
    try:
        return _analyse_trial(metadata, recording, emg, params)
    except RecordingError as exc:
        raise RecordingError(f"{trial_label(metadata)}: {exc}") from None


def _analyse_trial(
    metadata: TrialMetadata, recording: pd.DataFrame, emg: pd.DataFrame | None, params: AnalysisParameters
) -> TrialOutcomes:
    missing = [c for c in _REQUIRED if c not in recording.columns]
    if missing:
        raise RecordingError(f"trial recording lacks column(s) {missing}")
    segmentation = segment_repetitions(recording, params.segmentation)
    time = np.asarray(recording[TRIAL_TIME], dtype=np.float64)
    rate = (time.size - 1) / (time[-1] - time[0])
    column = {name: np.asarray(recording[name], dtype=np.float64) for name in _REQUIRED}
    moment_arm = column[TRIAL_MOMENT_ARM]
    signals = {
        "reference_elevation_rad": column[TRIAL_REFERENCE_ELEVATION],
        "elevation_rad": column[TRIAL_ELEVATION],
        "desired_tension_n": column[TRIAL_DESIRED_TENSION],
        "tension_n": column[TRIAL_TENSION],
        "desired_torque_nm": column[TRIAL_DESIRED_TENSION] * moment_arm,
        "torque_nm": column[TRIAL_TENSION] * moment_arm,
    }
    speed_abs = np.abs(column[TRIAL_ELEVATION_VELOCITY])
    n_points = params.segmentation.n_points
    rows: list[tuple[str, str, str, int, str, str, float]] = []
    m = metadata

    def add(rep: Repetition, phase: str, measure: str, value: float) -> None:
        if math.isfinite(value):
            rows.append((m.participant, m.condition, m.speed, rep.number, phase, measure, float(value)))

    curves = np.empty((len(segmentation.repetitions), n_points, len(CURVE_SIGNALS)))
    for i, rep in enumerate(segmentation.repetitions):
        phases = {
            "entire": (time >= rep.start_s) & (time <= rep.end_s),
            "raising": (time >= rep.start_s) & (time <= rep.turn_s),
            "lowering": (time >= rep.turn_s) & (time <= rep.end_s),
        }
        bounds = {
            "entire": (rep.start_s, rep.end_s),
            "raising": (rep.start_s, rep.turn_s),
            "lowering": (rep.turn_s, rep.end_s),
        }
        for phase, mask in phases.items():
            for measure, value in _tension_measures(signals, time, mask, rep, phase, params):
                add(rep, phase, measure, value)
            add(
                rep,
                phase,
                ELEVATION_RMSE,
                rmse(signals["elevation_rad"][mask], signals["reference_elevation_rad"][mask]),
            )
            add(rep, phase, SPARC, _phase_sparc(time, speed_abs, *bounds[phase], rate, params.sparc))
        stacked = np.column_stack([signals[name] for name in CURVE_SIGNALS])
        curves[i] = resample_repetition(time, stacked, rep, n_points)
    emg_curves, emg_peaks, channels, rates = _emg_outcomes(emg, segmentation.repetitions, params)
    return TrialOutcomes(
        metadata=metadata,
        rows=rows,
        repetitions=segmentation.repetitions,
        curves=curves,
        emg_curves=emg_curves,
        emg_peaks=emg_peaks,
        emg_channels=channels,
        segmentation_source=segmentation.source,
        heart_rate_bpm=rates,
    )


def _tension_measures(signals: dict[str, NDArray[np.float64]], time: NDArray[np.float64],
                      mask: NDArray[np.bool_], rep: Repetition, phase: str,
                      params: AnalysisParameters) -> list[tuple[str, float]]:
    """The tension and torque errors of one phase of one repetition (none where tension is missing)."""
    tension, desired = signals["tension_n"][mask], signals["desired_tension_n"][mask]
    if not (np.any(np.isfinite(tension)) and np.any(np.isfinite(desired))):
        return []
    error = percent_error(tension, desired, min_reference=params.min_reference_tension_n)
    measures = [
        (TENSION_RMSE, rmse(tension, desired)),
        (TORQUE_RMSE, rmse(signals["torque_nm"][mask], signals["desired_torque_nm"][mask])),
        (PERCENT_ERROR_RMSE, root_mean_square(error)),
    ]
    if phase != "entire":
        peak, index = signed_peak(error)
        if index >= 0:
            peak_time = time[mask][index]
            measures += [(PEAK_PERCENT_ERROR, peak),
                         (PEAK_PERCENT_ERROR_TIME, 100.0 * (peak_time - rep.start_s) / rep.duration_s)]
    return measures


def _emg_outcomes(
    emg: pd.DataFrame | None, repetitions: Sequence[Repetition], params: AnalysisParameters
) -> tuple[NDArray[np.float64] | None, dict[str, float] | None, tuple[str, ...], dict[str, float]]:
    """Per-repetition envelope curves and mean peaks, the channels, and the heart rates the ECG
    removal found (nothing without EMG)."""
    if emg is None:
        return None, None, (), {}
    channels = tuple(name for name in MUSCLES if name in emg.columns) or tuple(
        str(c) for c in emg.columns if c != TRIAL_TIME
    )
    result = emg_pipeline(EmgSignal.from_frame(emg, channels=channels), params.emg)
    envelope = result.envelope
    n_points = params.segmentation.n_points
    curves = np.stack([resample_repetition(envelope.time_s, envelope.values, rep, n_points)
                       for rep in repetitions])
    return curves, emg_mean_peak(envelope, repetitions), channels, result.info.heart_rate_bpm


def _phase_sparc(
    time: NDArray[np.float64],
    speed: NDArray[np.float64],
    start: float,
    end: float,
    rate: float,
    params: SparcParameters,
) -> float:
    """SPARC of |θ̇| between two times, resampled onto a uniform grid at the trial's mean rate."""
    grid = np.arange(start, end + 0.5 / rate, 1.0 / rate)
    grid = grid[grid <= end + 1e-12]
    if grid.size < 2 or not np.all(np.isfinite(speed)):
        return math.nan
    profile = np.interp(grid, time, speed)
    if not np.any(profile > 0.0):
        return math.nan
    return sparc(profile, rate, params)


def trial_label(metadata: TrialMetadata) -> str:
    """``participant …, condition, speed`` for messages."""
    return f"participant {metadata.participant}, {metadata.condition}, {metadata.speed}"
