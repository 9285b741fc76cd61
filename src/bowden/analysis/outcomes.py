"""A study's trials → the paper's outcome measures as one tidy table, plus mean ± SD curves.

Entry point: :func:`analyse_study` takes an iterable of ``(metadata, recording)`` or
``(metadata, recording, emg)``: ``recording`` is a trial DataFrame with the ``bowden.contracts``
``TRIAL_*`` columns, ``emg`` a DataFrame with ``time_s`` (controller time base) and one column per
muscle at 2 kHz, or ``None``. Nothing here reads a database: the study store hands the DataFrames.

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
  SPARC was designed; the entire cycle (two bells) is what the paper's values (≈ −2.4…−2.8) suggest;
* ``iemg_<muscle>`` — integral over normalised time (0…1 across the whole repetition) of the
  envelope normalised to the mean no-suit peak (per participant and speed); raising + lowering =
  entire.

Error measures use the recorded samples inside each phase; curves and iEMG use the normalised grid.
Tension measures are omitted for trials without load-cell data (e.g. no suit).
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from bowden.analysis.emg_normalize import emg_mean_peak
from bowden.analysis.emg_process import EmgProcessParameters, emg_pipeline
from bowden.analysis.emg_signal import EmgSignal
from bowden.analysis.metrics import integrate_between, percent_error, rmse, root_mean_square, signed_peak
from bowden.analysis.segmentation import (
    Repetition,
    SegmentationParameters,
    normalised_time,
    resample_repetition,
    segment_repetitions,
)
from bowden.analysis.sparc import SparcParameters, sparc
from bowden.contracts import (
    CONDITION_NO_SUIT,
    CONDITIONS,
    MUSCLES,
    PHASES,
    SPEEDS,
    TRIAL_DESIRED_TENSION,
    TRIAL_ELEVATION,
    TRIAL_ELEVATION_VELOCITY,
    TRIAL_MOMENT_ARM,
    TRIAL_REFERENCE_ELEVATION,
    TRIAL_TENSION,
    TRIAL_TIME,
)
from bowden.errors import ParameterError, RecordingError

OUTCOME_COLUMNS = ("participant", "condition", "speed", "repetition", "phase", "measure", "value")
CURVE_COLUMNS = ("participant", "condition", "speed", "signal", "normalised_time", "mean", "sd", "n")
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
        if self.condition not in CONDITIONS:
            raise ParameterError(f"condition must be one of {CONDITIONS}, got {self.condition!r}")
        if self.speed not in SPEEDS:
            raise ParameterError(f"speed must be one of {SPEEDS}, got {self.speed!r}")

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


@dataclass(frozen=True, kw_only=True)
class AnalysisInfo:
    """How the study was analysed: counts, choices and anything left out (with the reason)."""

    parameters: AnalysisParameters
    n_trials: int
    n_participants: int
    n_repetitions: int
    segmentation_sources: dict[str, int]
    notes: tuple[str, ...]
    heart_rate_bpm: dict[str, float]


@dataclass(frozen=True, kw_only=True)
class StudyOutcomes:
    """The tidy outcome table, mean ± SD curves on normalised time, and the analysis info."""

    outcomes: pd.DataFrame
    curves: pd.DataFrame
    info: AnalysisInfo

    def rmse_table(self, measure: str = TENSION_RMSE) -> pd.DataFrame:
        """The paper's RMSE layout: conditions x (speed, phase), mean over participants' means."""
        data = self.outcomes[self.outcomes["measure"] == measure]
        if data.empty:
            raise RecordingError(f"no {measure!r} values in the outcome table")
        per_participant = data.groupby(["participant", "condition", "speed", "phase"])["value"].mean()
        means = per_participant.groupby(["condition", "speed", "phase"]).mean()
        table = pd.DataFrame(means.unstack(["speed", "phase"]))
        order = [c for c in CONDITIONS if c in table.index]
        columns = pd.MultiIndex.from_tuples(
            [(s, p) for s in SPEEDS for p in PHASES if (s, p) in table.columns], names=["speed", "phase"]
        )
        return table.reindex(index=order, columns=columns)


@dataclass
class _TrialResult:
    metadata: TrialMetadata
    rows: list[tuple[str, str, str, int, str, str, float]]
    repetitions: tuple[Repetition, ...]
    curves: NDArray[np.float64]  # repetitions x points x CURVE_SIGNALS
    emg_curves: NDArray[np.float64] | None  # repetitions x points x muscles, V
    emg_peaks: dict[str, float] | None  # mean per-repetition peak, V
    emg_channels: tuple[str, ...]


def analyse_study(
    trials: Iterable[tuple[Any, ...]], parameters: AnalysisParameters | None = None
) -> StudyOutcomes:
    """Analyse every trial of a study and return :class:`StudyOutcomes`.

    Parameters
    ----------
    trials
        ``(metadata, recording)`` or ``(metadata, recording, emg)`` tuples; ``metadata`` is a
        :class:`TrialMetadata` or a mapping with ``participant``, ``condition``, ``speed``.
    parameters
        Settings of every step; defaults reproduce the paper.
    """
    params = parameters or AnalysisParameters()
    results: list[_TrialResult] = []
    notes: list[str] = []
    sources: dict[str, int] = defaultdict(int)
    heart_rates: dict[str, list[float]] = defaultdict(list)
    for item in trials:
        if len(item) not in (2, 3):
            raise ParameterError("each trial must be (metadata, recording) or (metadata, recording, emg)")
        metadata = TrialMetadata.coerce(item[0])
        emg = item[2] if len(item) == 3 else None
        try:
            result, source, rates = _analyse_trial(metadata, item[1], emg, params)
        except RecordingError as exc:
            raise RecordingError(f"{_label(metadata)}: {exc}") from None
        sources[source] += 1
        for name, rate in rates.items():
            heart_rates[name].append(rate)
        results.append(result)
    if not results:
        raise ParameterError("analyse_study needs at least one trial")
    references = _no_suit_references(results)
    rows = [row for result in results for row in result.rows]
    curve_frames = []
    tau = normalised_time(params.segmentation.n_points)
    for result in results:
        normalised = None
        if result.emg_curves is not None:
            key = (result.metadata.participant, result.metadata.speed)
            if key not in references:
                notes.append(
                    f"{_label(result.metadata)}: no no-suit EMG for this participant and speed; iEMG left out"
                )
            else:
                scale = np.asarray([references[key][name] for name in result.emg_channels])
                normalised = result.emg_curves / scale
                rows.extend(_iemg_rows(result, normalised, tau))
        curve_frames.append(_mean_sd_curves(result, normalised, tau, params.curve_points))
    outcomes = pd.DataFrame.from_records(rows, columns=list(OUTCOME_COLUMNS))
    info = AnalysisInfo(
        parameters=params,
        n_trials=len(results),
        n_participants=len({r.metadata.participant for r in results}),
        n_repetitions=sum(len(r.repetitions) for r in results),
        segmentation_sources=dict(sources),
        notes=tuple(notes),
        heart_rate_bpm={name: float(np.nanmean(v)) for name, v in heart_rates.items()},
    )
    return StudyOutcomes(outcomes=outcomes, curves=pd.concat(curve_frames, ignore_index=True), info=info)


def _analyse_trial(
    metadata: TrialMetadata, recording: pd.DataFrame, emg: pd.DataFrame | None, params: AnalysisParameters
) -> tuple[_TrialResult, str, dict[str, float]]:
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
            tension, desired = signals["tension_n"][mask], signals["desired_tension_n"][mask]
            has_tension = bool(np.any(np.isfinite(tension)) and np.any(np.isfinite(desired)))
            if has_tension:
                add(rep, phase, TENSION_RMSE, rmse(tension, desired))
                add(
                    rep,
                    phase,
                    TORQUE_RMSE,
                    rmse(signals["torque_nm"][mask], signals["desired_torque_nm"][mask]),
                )
                error = percent_error(tension, desired, min_reference=params.min_reference_tension_n)
                add(rep, phase, PERCENT_ERROR_RMSE, root_mean_square(error))
                if phase != "entire":
                    peak, index = signed_peak(error)
                    if index >= 0:
                        add(rep, phase, PEAK_PERCENT_ERROR, peak)
                        peak_time = time[mask][index]
                        add(
                            rep,
                            phase,
                            PEAK_PERCENT_ERROR_TIME,
                            100.0 * (peak_time - rep.start_s) / rep.duration_s,
                        )
            add(
                rep,
                phase,
                ELEVATION_RMSE,
                rmse(signals["elevation_rad"][mask], signals["reference_elevation_rad"][mask]),
            )
            add(rep, phase, SPARC, _phase_sparc(time, speed_abs, *bounds[phase], rate, params.sparc))
        stacked = np.column_stack([signals[name] for name in CURVE_SIGNALS])
        curves[i] = resample_repetition(time, stacked, rep, n_points)
    emg_curves = None
    emg_peaks = None
    channels: tuple[str, ...] = ()
    rates: dict[str, float] = {}
    if emg is not None:
        channels = tuple(name for name in MUSCLES if name in emg.columns) or tuple(
            str(c) for c in emg.columns if c != TRIAL_TIME
        )
        result = emg_pipeline(EmgSignal.from_frame(emg, channels=channels), params.emg)
        rates = result.info.heart_rate_bpm
        envelope = result.envelope
        emg_peaks = emg_mean_peak(envelope, segmentation.repetitions)
        emg_curves = np.stack(
            [
                resample_repetition(envelope.time_s, envelope.values, rep, n_points)
                for rep in segmentation.repetitions
            ]
        )
    trial = _TrialResult(
        metadata=metadata,
        rows=rows,
        repetitions=segmentation.repetitions,
        curves=curves,
        emg_curves=emg_curves,
        emg_peaks=emg_peaks,
        emg_channels=channels,
    )
    return trial, segmentation.source, rates


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


def _no_suit_references(results: list[_TrialResult]) -> dict[tuple[str, str], dict[str, float]]:
    """Mean no-suit peak per (participant, speed) and muscle, pooled over no-suit trials."""
    pooled: dict[tuple[str, str], list[dict[str, float]]] = defaultdict(list)
    for result in results:
        if result.metadata.condition == CONDITION_NO_SUIT and result.emg_peaks is not None:
            pooled[(result.metadata.participant, result.metadata.speed)].append(result.emg_peaks)
    return {
        key: {name: float(np.mean([p[name] for p in peaks])) for name in peaks[0]}
        for key, peaks in pooled.items()
    }


def _iemg_rows(
    result: _TrialResult, normalised: NDArray[np.float64], tau: NDArray[np.float64]
) -> list[tuple[str, str, str, int, str, str, float]]:
    m = result.metadata
    rows = []
    for i, rep in enumerate(result.repetitions):
        turn = rep.turn_fraction
        for j, name in enumerate(result.emg_channels):
            curve = normalised[i, :, j]
            for phase, (lo, hi) in (
                ("entire", (0.0, 1.0)),
                ("raising", (0.0, turn)),
                ("lowering", (turn, 1.0)),
            ):
                rows.append(
                    (
                        m.participant,
                        m.condition,
                        m.speed,
                        rep.number,
                        phase,
                        IEMG_PREFIX + name,
                        integrate_between(tau, curve, lo, hi),
                    )
                )
    return rows


def _mean_sd_curves(
    result: _TrialResult, normalised: NDArray[np.float64] | None, tau: NDArray[np.float64], points: int
) -> pd.DataFrame:
    """Mean and SD (ddof=1) across repetitions of each signal, on a ``points`` grid 0…1."""
    names = list(CURVE_SIGNALS)
    data = result.curves
    if normalised is not None:
        names += [f"emg_{name}" for name in result.emg_channels]
        data = np.concatenate([data, normalised], axis=2)
    grid = normalised_time(points)
    # Interpolate every repetition's curve onto the output grid (exact when the grids nest).
    coarse = np.stack(
        [
            np.stack([np.interp(grid, tau, data[r, :, s]) for s in range(data.shape[2])], axis=1)
            for r in range(data.shape[0])
        ]
    )
    finite = np.isfinite(coarse)
    count = np.sum(finite, axis=0)
    filled = np.where(finite, coarse, 0.0)
    # Explicit sums rather than nanmean/nanstd: signals absent in a trial (tension without a load
    # cell) are all-NaN and must give NaN quietly, and one repetition has no SD.
    mean = np.divide(filled.sum(axis=0), count, out=np.full(count.shape, np.nan), where=count > 0)
    squares = np.where(finite, (coarse - mean) ** 2, 0.0).sum(axis=0)
    sd = np.sqrt(np.divide(squares, count - 1, out=np.full(count.shape, np.nan), where=count > 1))
    m = result.metadata
    frame = pd.DataFrame(
        {
            "participant": m.participant,
            "condition": m.condition,
            "speed": m.speed,
            "signal": np.repeat(names, points),
            "normalised_time": np.tile(grid, len(names)),
            "mean": mean.T.ravel(),
            "sd": sd.T.ravel(),
            "n": count.T.ravel(),
        }
    )
    return frame


def _label(metadata: TrialMetadata) -> str:
    return f"participant {metadata.participant}, {metadata.condition}, {metadata.speed}"
