"""The study-like segment as a bench recorded it: judged per (support, speed) cell and compensation.

``bowden bench run`` writes the study-like strokes to ``<stem>.study.csv`` (docs/identification.md,
"The protocol, exactly": its columns). Each block is one support, speed and compensation; its
repetitions are numbered by ``cycle_phase`` (the cycle number plus the fraction of the cycle, negative
during the rest before the first). Judged as the batch segment (:mod:`bowden.sim.bench_study`) judges
its own, with the same measures (:mod:`bowden.identify.study_fit`): on the repetitions after the
first, the tension RMSE of the load cell (``tension_n``) against the support law at the mannequin
joint's elevation (``law_tension_n``), and the lowering-onset peak (the largest percent error of the
repetition-mean curve, in 1 % bins of the cycle, between 45 % and 75 %); the same measures of each
held-out repetition alone for the recommendation's paired bound.

A study-like fit on a bench (``bowden bench validate --fit``) records its blocks in the same file,
marked by ``fit`` (1) and ``candidate`` (the index into :func:`bowden.identify.study_fit.fit_grid`; −1
for its paper's blocks), before the study-like blocks it is validated on: :func:`choose_fitted`
judges them by the batch fit's :func:`~bowden.identify.study_fit.study_cost`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bowden.errors import FitError
from bowden.identify.study_fit import (
    Cell,
    StrokeResult,
    fit_candidate,
    fit_grid,
    lowest_cost,
    onset_peak_pct,
    study_cost,
)
from bowden.model import CompensationModel
from bowden.model.dynamic import support_label

REQUIRED = ("block", "support", "speed", "compensation", "cycle_phase", "tension_n", "law_tension_n")
# A last repetition whose rows end before this fraction of its cycle was recorded only in part: left out.
WHOLE_CYCLE = 0.95
SPEEDS = {1: "V1", 2: "V2", 3: "V3"}
COMPENSATIONS = {0: "paper", 1: "dynamic"}


def covers_its_cycles(cycle_phase: NDArray[np.float64], repetitions: int) -> bool:
    """Whether a block's rows reach the end of its last cycle (:data:`WHOLE_CYCLE` of it), so that
    :func:`judge_block` keeps every repetition after the first."""
    return cycle_phase.size > 0 and float(cycle_phase.max()) >= repetitions - 1 + WHOLE_CYCLE


def judge_block(cycle_phase: NDArray[np.float64], tension_n: NDArray[np.float64],
                law_tension_n: NDArray[np.float64]) -> StrokeResult:
    """One block's result on its repetitions after the first (``cycle_phase`` ≥ 1)."""
    # The repetitions after the first; a last one recorded only in part (the bench stopped recording
    # before its end) is left out.
    held_out = cycle_phase >= 1.0
    last = math.floor(float(cycle_phase.max())) if cycle_phase.size else 0
    if last >= 1 and float(cycle_phase.max()) - last < WHOLE_CYCLE:
        held_out &= cycle_phase < last
    phase = cycle_phase[held_out]
    error = tension_n[held_out] - law_tension_n[held_out]
    if error.size == 0:
        raise FitError("a study-like block holds no repetition after the first")
    fraction = phase % 1.0
    percent = 100.0 * error / law_tension_n[held_out]
    stroke = np.floor(phase).astype(int)
    strokes = [stroke == r for r in np.unique(stroke)]
    # Each repetition's own measures too: the paired bound of the recommendation is taken from them.
    return StrokeResult(
        float(np.sqrt(np.mean(error**2))), onset_peak_pct(fraction, percent),
        stroke_rmse_n=tuple(float(np.sqrt(np.mean(error[one] ** 2))) for one in strokes),
        stroke_peak_pct=tuple(onset_peak_pct(fraction[one], percent[one]) for one in strokes),
    )


def _read_frame(path: str | Path, flag: str) -> Any:
    import pandas as pd

    try:
        frame = pd.read_csv(path)
    except (OSError, ValueError) as error:
        raise FitError(f"{flag} {path}: cannot be read ({error})") from None
    missing = [name for name in REQUIRED if name not in frame.columns]
    if missing:
        raise FitError(f"{flag} {path}: missing column(s) {', '.join(missing)} (the study-like "
                       "segment of `bowden bench run`, docs/identification.md)")
    if frame.empty or not np.isfinite(frame[list(REQUIRED)].to_numpy(dtype=np.float64)).all():
        raise FitError(f"{flag} {path}: empty, or non-finite values in {', '.join(REQUIRED)}")
    # A recording without them (before the fit on a bench existed, or another bench's) holds no fit.
    for name, absent in (("fit", 0), ("candidate", -1)):
        if name not in frame.columns:
            frame[name] = absent
    if not np.isfinite(frame[["fit", "candidate"]].to_numpy(dtype=np.float64)).all():
        raise FitError(f"{flag} {path}: non-finite values in fit, candidate")
    return frame


@dataclass(frozen=True)
class _Judged:
    """One block of the recording judged, with what it was."""

    cell: Cell
    compensation: str
    result: StrokeResult
    fit: bool
    candidate: int


def _judged_blocks(path: str | Path, flag: str) -> list[_Judged]:
    """Every block of the recording judged, in the order of its ``block`` numbers."""
    judged = []
    for block, rows in _read_frame(path, flag).groupby("block", sort=True):
        support = float(rows["support"].iloc[0])
        speed = SPEEDS.get(int(rows["speed"].iloc[0]))
        name = COMPENSATIONS.get(int(rows["compensation"].iloc[0]))
        if speed is None or name is None:
            raise FitError(f"{flag} {path}: block {block} has an unknown speed or compensation code")
        cell = (support_label("pretension" if support == 0.0 else support), speed)
        try:
            result = judge_block(rows["cycle_phase"].to_numpy(np.float64),
                                 rows["tension_n"].to_numpy(np.float64),
                                 rows["law_tension_n"].to_numpy(np.float64))
        except FitError as error:
            raise FitError(f"{flag} {path}, block {block}: {error}") from None
        fit, candidate = bool(rows["fit"].iloc[0]), int(rows["candidate"].iloc[0])
        judged.append(_Judged(cell, name, result, fit, candidate if fit else -1))
    return judged


def read_study_recording(path: str | Path, flag: str = "--study-recording", *, after_fit: bool = False,
                         ) -> dict[Cell, dict[str, StrokeResult]]:
    """The recorded study-like segment judged per (support label, speed) → compensation → result;
    a bad file is a :class:`FitError` naming ``flag``.

    The blocks of a study-like fit (``fit`` = 1) are not among them; a recording that holds them is
    refused unless ``after_fit``: its study-like blocks ran the candidate the fit chose, not the model
    given (:func:`choose_fitted` gives it)."""
    judged = _judged_blocks(path, flag)
    if any(one.fit for one in judged) and not after_fit:
        raise FitError(f"{flag} {path}: holds a study-like fit (`bench validate --fit`): its blocks after "
                       "the fit ran the candidate it chose; judge it with `bowden bench validate MODEL "
                       f"--recording {path} --fit`")
    results: dict[Cell, dict[str, StrokeResult]] = {}
    for one in judged:
        if not one.fit:
            results.setdefault(one.cell, {})[one.compensation] = one.result
    if not results:
        raise FitError(f"{flag} {path}: holds no study-like blocks after the fit (the held-out "
                       "validation): the run stopped before them; --resume it")
    return results


@dataclass(frozen=True)
class FitChoice:
    """What a recorded study-like fit chose: the candidate (its index into
    :func:`~bowden.identify.study_fit.fit_grid`), the model with it applied, and every candidate's
    :func:`~bowden.identify.study_fit.study_cost`."""

    candidate: int
    model: CompensationModel
    costs: dict[int, float]


def fit_results(path: str | Path, flag: str) -> dict[int, dict[Cell, dict[str, StrokeResult]]]:
    """The recorded fit's blocks, per candidate: (support label, speed) → ``"paper"`` (the fit's
    paper block at that speed) and ``"dynamic"`` (the candidate's); a fit with a block missing (the
    run stopped within it) is a :class:`FitError` saying which."""
    paper: dict[Cell, StrokeResult] = {}
    candidates: dict[int, dict[Cell, StrokeResult]] = {}
    for one in _judged_blocks(path, flag):
        if one.fit and one.candidate < 0:
            paper[one.cell] = one.result
        elif one.fit:
            candidates.setdefault(one.candidate, {})[one.cell] = one.result
    if not candidates:
        raise FitError(f"{flag} {path}: holds no candidate blocks of a study-like fit (columns fit and "
                       "candidate; `bowden bench validate MODEL --backend can --fit` records them)")
    for candidate, cells in sorted(candidates.items()):
        missing = sorted(set(paper) ^ set(cells))
        if missing:
            raise FitError(f"{flag} {path}: the study-like fit is incomplete: candidate {candidate} and the "
                           f"paper's blocks differ in {', '.join(' '.join(cell) for cell in missing)} "
                           "(the run stopped within the fit: --resume it)")
    return {candidate: {cell: {"paper": paper[cell], "dynamic": result} for cell, result in cells.items()}
            for candidate, cells in sorted(candidates.items())}


def choose_fitted(model: CompensationModel, path: str | Path, flag: str) -> FitChoice:
    """The candidate of the recorded fit with the lowest study cost — the batch fit's function and
    grid (:mod:`bowden.identify.study_fit`, as :func:`bowden.sim.bench_study.fit_on_study_segment`) on
    the bench's strokes."""
    costs = {candidate: study_cost(results) for candidate, results in fit_results(path, flag).items()}
    best = lowest_cost(costs)
    if best is None:
        raise FitError(f"{flag} {path}: no candidate of the study-like fit has a finite cost")
    if best >= len(fit_grid()):
        raise FitError(f"{flag} {path}: candidate {best} is not in the fit's grid of {len(fit_grid())}")
    return FitChoice(best, fit_candidate(model, best), costs)
