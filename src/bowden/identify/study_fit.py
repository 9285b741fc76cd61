"""The study-like fit: its grid of candidates, their cost, and the measures of a study-like stroke.

The study-like segment (docs/identification.md, segment 3; docs/dynamic_compensation.md, "Which
compensation") runs the study's minimum-jerk cycle on a bench with each compensation and measures,
on the repetitions after the first, the tension RMSE against the support law and the lowering-onset
peak (:class:`StrokeResult`). Its fit refits the dynamic compensation on those strokes: each candidate
of :func:`fit_grid` (drag and inertia scaled, the lowering line shifted) runs the same strokes, and
the one of lowest :func:`study_cost` is kept.

Nothing here simulates: the batch simulated bench (:mod:`bowden.sim.bench_study`) and a real bench's
recording (:mod:`bowden.identify.study_recording`) both measure their strokes and choose with these.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from bowden.errors import FitError
from bowden.model import CompensationModel

# Where in the cycle (fractions of it) the lowering-onset peak is taken: the largest percent error of
# the repetition-mean curve between 45 % and 75 % of the cycle (docs/dynamic_compensation.md).
ONSET_WINDOW = (0.45, 0.75)

# The supports of the study's conditions the segment runs (pretension, 25 %, 50 %), each at V1-V3.
STUDY_SUPPORTS: tuple[float | str, ...] = ("pretension", 0.25, 0.5)

Cell = tuple[str, str]  # (support label, speed)


@dataclass(frozen=True)
class StrokeResult:
    """Tension RMSE (N) against the support law at the true elevation, and the lowering-onset peak (%
    of the reference, repetition-mean curve between 45 % and 75 % of the cycle), held-out repetitions;
    ``stroke_rmse_n`` and ``stroke_peak_pct`` are the same measures of each held-out repetition alone,
    in order (the paired differences the recommendation's bound is taken from)."""

    tension_rmse_n: float
    onset_peak_pct: float
    stroke_rmse_n: tuple[float, ...] = ()
    stroke_peak_pct: tuple[float, ...] = ()


def onset_curve(fraction: NDArray[np.float64], percent: NDArray[np.float64]) -> NDArray[np.float64]:
    """The percent error binned over the cycle (1 % bins, by the samples' ``fraction`` of it): the
    bins inside the onset window that hold a sample."""
    bins = np.minimum((fraction * 100).astype(int), 99)
    counts = np.bincount(bins, minlength=100)
    curve = np.bincount(bins, weights=percent, minlength=100) / np.maximum(counts, 1)
    centres = (np.arange(100) + 0.5) / 100
    window = (centres >= ONSET_WINDOW[0]) & (centres <= ONSET_WINDOW[1]) & (counts > 0)
    return curve[window]


def onset_peak_pct(fraction: NDArray[np.float64], percent: NDArray[np.float64]) -> float:
    """Largest percent error of the curve binned over the cycle inside the onset window
    (:func:`onset_curve`); a :class:`FitError` when no sample falls in it."""
    onset = onset_curve(fraction, percent)
    if not onset.size:
        raise FitError("a study-like block holds no sample in the lowering onset (45-75 % of the cycle)")
    return float(onset.max())


# The grid the study-like fit searches: scale on the identified drag and inertia, shift of the lowering
# line's intercept (Nm). Drag and a lower lowering line both release the cable earlier at a turn, which
# the bench's steady strokes cannot show (presliding, capstan friction growing with tension, play).
FIT_DRAG_SCALES = (1.0, 1.4, 1.8)
FIT_INERTIA_SCALES = (1.0, 2.0)
FIT_LOWERING_SHIFTS_NM = (0.0, -0.05)
# Cycles per block of the fit's strokes (the first is not judged): the batch fit's and a bench's.
FIT_REPETITIONS = 4


def fit_grid() -> tuple[tuple[float, float, float], ...]:
    """The fit's candidates in the order searched, each (drag scale, inertia scale, lowering shift Nm):
    candidate k of a bench's fit (the study recording's ``candidate`` column) is the k-th."""
    return tuple((drag, inertia, shift) for drag in FIT_DRAG_SCALES for inertia in FIT_INERTIA_SCALES
                 for shift in FIT_LOWERING_SHIFTS_NM)


def fit_candidate(model: CompensationModel, index: int) -> CompensationModel:
    """``model`` with candidate ``index`` of :func:`fit_grid` applied to its dynamic compensation
    (drag and inertia scaled within their bounds, the lowering line's intercept shifted)."""
    dynamic = model.dynamic
    if dynamic is None:
        raise FitError("the model has no dynamic compensation to refit")
    drag, inertia, shift = fit_grid()[index]
    return replace(model, dynamic=replace(
        dynamic,
        viscous_nm_s_rad=min(1.0, dynamic.viscous_nm_s_rad * drag),
        inertia_kg_m2=min(0.05, dynamic.inertia_kg_m2 * inertia),
        lowering=replace(dynamic.lowering, intercept_nm=dynamic.lowering.intercept_nm + shift),
    ))


def lowest_cost(costs: dict[int, float]) -> int | None:
    """The candidate with the lowest :func:`study_cost`, the first in grid order on a tie; None if no
    cost is finite (the batch fit then keeps the model as identified)."""
    best, best_cost = None, math.inf
    for index in sorted(costs):
        if costs[index] < best_cost:
            best, best_cost = index, costs[index]
    return best


def study_cost(results: dict[Cell, dict[str, StrokeResult]]) -> float:
    """Mean over speeds of the dynamic compensation's RMSE and onset peak, each relative to the paper's."""
    terms = []
    for by_name in results.values():
        paper, dynamic = by_name["paper"], by_name["dynamic"]
        terms.append(dynamic.tension_rmse_n / max(paper.tension_rmse_n, 1e-6)
                     + max(dynamic.onset_peak_pct, 0.0) / max(paper.onset_peak_pct, 1.0))
    return float(np.mean(terms))
