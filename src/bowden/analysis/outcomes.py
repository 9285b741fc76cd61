"""A study's trials → the paper's outcome measures as one tidy table, plus mean ± SD curves.

Entry point: :func:`analyse_study` takes an iterable of ``(metadata, recording)`` or
``(metadata, recording, emg)``: ``recording`` is a trial DataFrame with the ``bowden.contracts``
``TRIAL_*`` columns, ``emg`` a DataFrame with ``time_s`` (controller time base) and one column per
muscle at 2 kHz, or ``None``. Nothing here reads a database: the study store hands the DataFrames.

Each trial is analysed alone by :func:`bowden.analysis.trial_outcomes.analyse_trial` (the measures
are listed there), ``workers`` of them at a time; this module does what needs the whole study:

* ``iemg_<muscle>`` — integral over normalised time (0…1 across the whole repetition) of the
  envelope normalised to the mean no-suit peak (per participant and speed); raising + lowering =
  entire;
* mean ± SD curves on normalised time per participant, condition and speed;
* the :class:`AnalysisInfo` that the methods text and the report read.
"""

from __future__ import annotations

import functools
import multiprocessing
from collections import defaultdict
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from bowden.analysis.metrics import integrate_columns_between
from bowden.analysis.segmentation import normalised_time
from bowden.analysis.trial_outcomes import (
    CURVE_SIGNALS,
    ELEVATION_RMSE,
    IEMG_PREFIX,
    OUTCOME_COLUMNS,
    PEAK_PERCENT_ERROR,
    PEAK_PERCENT_ERROR_TIME,
    PERCENT_ERROR_RMSE,
    SPARC,
    TENSION_RMSE,
    TORQUE_RMSE,
    AnalysisParameters,
    TrialMetadata,
    TrialOutcomes,
    analyse_trial,
    trial_label,
)
from bowden.contracts import CONDITION_NO_SUIT, CONDITIONS, PHASES, SPEEDS
from bowden.errors import ParameterError, RecordingError

# The outcome table's column naming the trial of each row (the store's trial id, as in the samples).
TRIAL_ID = "trial_id"

# Names of the outcome table that callers import from here, as they did before the trial level
# moved to its own module.
__all__ = [
    "CURVE_COLUMNS",
    "ELEVATION_RMSE",
    "IEMG_PREFIX",
    "OUTCOME_COLUMNS",
    "PEAK_PERCENT_ERROR",
    "PEAK_PERCENT_ERROR_TIME",
    "PERCENT_ERROR_RMSE",
    "SPARC",
    "TENSION_RMSE",
    "TORQUE_RMSE",
    "TRIAL_ID",
    "AnalysisInfo",
    "AnalysisParameters",
    "StudyOutcomes",
    "TrialMetadata",
    "analyse_study",
]

CURVE_COLUMNS = ("participant", "condition", "speed", "signal", "normalised_time", "mean", "sd", "n")


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
        # The paper's conditions and speeds in its order, then a lab's own (sorted): none dropped.
        order = [*(c for c in CONDITIONS if c in table.index),
                 *sorted(c for c in table.index if c not in CONDITIONS)]
        present = {str(column[0]) for column in table.columns}
        speeds = [*(s for s in SPEEDS if s in present), *sorted(present - set(SPEEDS))]
        columns = pd.MultiIndex.from_tuples(
            [(s, p) for s in speeds for p in PHASES if (s, p) in table.columns], names=["speed", "phase"]
        )
        return table.reindex(index=order, columns=columns)


def analyse_study(
    trials: Iterable[tuple[Any, ...]], parameters: AnalysisParameters | None = None, *, workers: int = 1
) -> StudyOutcomes:
    """Analyse every trial of a study and return :class:`StudyOutcomes`.

    Parameters
    ----------
    trials
        ``(metadata, recording)`` or ``(metadata, recording, emg)`` tuples; ``metadata`` is a
        :class:`TrialMetadata` or a mapping with ``participant``, ``condition``, ``speed``.
        Consumed lazily: at most ``2·workers`` trials are held at a time.
    parameters
        Settings of every step; defaults reproduce the paper.
    workers
        Trials analysed at the same time, in worker processes (trials and results are pickled
        between them). The result does not depend on it: every trial is computed alone and
        the results are gathered in input order.
    """
    params = parameters or AnalysisParameters()
    if not (isinstance(workers, int) and workers >= 1):
        raise ParameterError(f"workers must be a positive integer, got {workers!r}")

    results = list(_ordered_map(functools.partial(_analyse_item, params=params), trials, workers))
    return combine_trial_outcomes(results, params)


def combine_trial_outcomes(
    results: list[TrialOutcomes], params: AnalysisParameters, trial_ids: Sequence[int] | None = None
) -> StudyOutcomes:
    """What needs the whole study, from every trial's :func:`analyse_trial` in study order.

    :func:`analyse_study` is this after its map; callers that analyse the trials on an engine of their
    own (``bowden study``'s worker pool or Dask) call it with the gathered results. The outcome table's
    :data:`TRIAL_ID` column names the trial of each row: ``trial_ids`` (the store's ids, one per
    result), else the trial's position in ``results`` from 1 — two trials of one participant,
    condition and speed stay apart.
    """
    if not results:
        raise ParameterError("analyse_study needs at least one trial")
    ids = list(range(1, len(results) + 1)) if trial_ids is None else [int(i) for i in trial_ids]
    if len(ids) != len(results) or len(set(ids)) != len(ids):
        raise ParameterError(f"trial_ids must give {len(results)} distinct ids, one per trial, got {ids}")
    sources: dict[str, int] = defaultdict(int)
    heart_rates: dict[str, list[float]] = defaultdict(list)
    for result in results:
        sources[result.segmentation_source] += 1
        for name, rate in result.heart_rate_bpm.items():
            heart_rates[name].append(rate)
    notes: list[str] = []
    references = _no_suit_references(results)
    rows = [row for result in results for row in result.rows]
    row_trials = [trial_id for trial_id, result in zip(ids, results, strict=True) for _ in result.rows]
    curve_frames = []
    tau = normalised_time(params.segmentation.n_points)
    for trial_id, result in zip(ids, results, strict=True):
        normalised = None
        if result.emg_curves is not None:
            key = (result.metadata.participant, result.metadata.speed)
            if key not in references:
                notes.append(
                    f"{trial_label(result.metadata)}: no no-suit EMG for this participant and speed; "
                    "iEMG left out"
                )
            else:
                scale = np.asarray([references[key][name] for name in result.emg_channels])
                normalised = result.emg_curves / scale
                iemg = _iemg_rows(result, normalised, tau)
                rows.extend(iemg)
                row_trials.extend([trial_id] * len(iemg))
        curve_frames.append(_mean_sd_curves(result, normalised, tau, params.curve_points))
    outcomes = pd.DataFrame.from_records(rows, columns=list(OUTCOME_COLUMNS))
    outcomes.insert(OUTCOME_COLUMNS.index("speed") + 1, TRIAL_ID, np.asarray(row_trials, dtype=np.int64))
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


def _analyse_item(item: tuple[Any, ...], params: AnalysisParameters) -> TrialOutcomes:
    """One trial of :func:`analyse_study` (module level, so that worker processes can run it)."""
    if len(item) not in (2, 3):
        raise ParameterError("each trial must be (metadata, recording) or (metadata, recording, emg)")
    emg = item[2] if len(item) == 3 else None
    return analyse_trial(TrialMetadata.coerce(item[0]), item[1], emg, params)


def _ordered_map(
    function: Callable[[tuple[Any, ...]], TrialOutcomes], items: Iterable[tuple[Any, ...]], workers: int
) -> Iterator[TrialOutcomes]:
    """``map(function, items)`` on ``workers`` processes, in input order, ≤ 2·workers items in flight.

    Processes, not threads: the EMG steps are many mid-sized NumPy operations whose Python
    overhead holds the GIL, and two threads measured no faster than one (benchmarks/analysis.py).
    """
    if workers == 1:
        yield from map(function, items)
        return
    # Fresh interpreters ("spawn"), not forks: the caller may hold threads (progress bars, a server)
    # whose locks a forked child would inherit mid-use.
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        pending: list[Future[TrialOutcomes]] = []
        for item in items:
            pending.append(pool.submit(function, item))
            if len(pending) >= 2 * workers:
                yield pending.pop(0).result()
        for future in pending:
            yield future.result()


def _no_suit_references(results: list[TrialOutcomes]) -> dict[tuple[str, str], dict[str, float]]:
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
    result: TrialOutcomes, normalised: NDArray[np.float64], tau: NDArray[np.float64]
) -> list[tuple[str, str, str, int, str, str, float]]:
    m = result.metadata
    rows = []
    for i, rep in enumerate(result.repetitions):
        turn = rep.turn_fraction
        # Every channel of the repetition at once (one grid, one pair of limits per phase).
        limits = {"entire": (0.0, 1.0), "raising": (0.0, turn), "lowering": (turn, 1.0)}
        phases = {
            phase: integrate_columns_between(tau, normalised[i], *ends) for phase, ends in limits.items()
        }
        for j, name in enumerate(result.emg_channels):
            for phase, integrals in phases.items():
                rows.append(
                    (m.participant, m.condition, m.speed, rep.number, phase, IEMG_PREFIX + name,
                     float(integrals[j]))
                )
    return rows


def _mean_sd_curves(
    result: TrialOutcomes, normalised: NDArray[np.float64] | None, tau: NDArray[np.float64], points: int
) -> pd.DataFrame:
    """Mean and SD (ddof=1) across repetitions of each signal, on a ``points`` grid 0…1."""
    names = list(CURVE_SIGNALS)
    data = result.curves
    if normalised is not None:
        names += [f"emg_{name}" for name in result.emg_channels]
        data = np.concatenate([data, normalised], axis=2)
    grid = normalised_time(points)
    coarse = interpolate_curves(grid, tau, data)
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


def interpolate_curves(
    grid: NDArray[np.float64], tau: NDArray[np.float64], data: NDArray[np.float64]
) -> NDArray[np.float64]:
    """``np.interp(grid, tau, data[r, :, s])`` for every repetition r and signal s at once.

    ``tau`` is increasing and ``grid`` inside it. Grid points on ``tau``'s points take their values
    exactly (the grids nest), as ``np.interp`` does; a NaN neighbour gives NaN, as it does there.
    """
    j = np.clip(np.searchsorted(tau, grid, side="right") - 1, 0, tau.size - 2)
    weight = ((grid - tau[j]) / (tau[j + 1] - tau[j]))[None, :, None]
    left, right = data[:, j, :], data[:, j + 1, :]
    between = left + weight * (right - left)
    on_left = np.where(weight == 0.0, left, between)
    return np.asarray(np.where(weight == 1.0, right, on_left))
