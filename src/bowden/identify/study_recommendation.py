"""Which compensation per (support, speed) cell: the recommendation rule of docs/dynamic_compensation.md.

From the study-like segment's results (:class:`~bowden.identify.study_fit.StrokeResult` per cell and
compensation, measured on the batch simulated bench or read from a bench's recording), the dynamic
compensation only where it beats the paper's with confidence on held-out strokes (every repetition
after the first): the upper 95 % bound of its RMSE and of its onset peak over the paper's, from the
paired strokes, below 1 (:func:`ratio_upper_bound`). Nothing here simulates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import t as student_t

from bowden.identify.study_fit import Cell, StrokeResult
from bowden.model import CompensationModel

# Repetitions per cell of the validation run: the first is dropped, the other six are the paired
# held-out strokes the recommendation's confidence bound is taken from (t quantile 2.02 with 5 degrees
# of freedom, against 2.92 with the fit's three).
VALIDATION_REPETITIONS = 7
CONFIDENCE = 0.95


@dataclass(frozen=True)
class Recommendation:
    """The choice per measured cell, whether dynamic won every cell, and one line why."""

    cells: tuple[tuple[str, str, bool], ...]
    everywhere: bool
    why: str

    def apply(self, model: CompensationModel) -> CompensationModel:
        """``model`` with this recommendation in its dynamic compensation (unchanged without one)."""
        if model.dynamic is None:
            return model
        return replace(model, dynamic=replace(model.dynamic, recommended=self.everywhere,
                                              recommendation=self.why, recommended_cells=self.cells))


def _label(cell: Cell) -> str:
    support, speed = cell
    return f"{support if support == 'pretension' else support + ' %'} {speed}"


def ratio_upper_bound(dynamic: tuple[float, ...], paper: tuple[float, ...],
                      confidence: float = CONFIDENCE) -> float:
    """One-sided upper confidence bound of mean(dynamic) / mean(paper) from paired strokes.

    The strokes are paired (the same stroke and sensor noise under either compensation), so the
    bound is taken on the mean paired difference d = dynamic − paper with Student's t (n − 1 degrees
    of freedom) and expressed relative to the paper's mean: 1 + (d̄ + t·s_d/√n) / mean(paper).
    Infinite (nothing is shown) with fewer than two strokes, unequal counts, or a paper's mean ≤ 0.
    """
    n = len(dynamic)
    if n < 2 or len(paper) != n or float(np.mean(paper)) <= 0.0:
        return math.inf
    difference = np.asarray(dynamic) - np.asarray(paper)
    spread = float(np.std(difference, ddof=1)) / math.sqrt(n)
    bound = float(np.mean(difference)) + float(student_t.ppf(confidence, n - 1)) * spread
    return 1.0 + bound / float(np.mean(paper))


def cell_bounds(paper: StrokeResult, dynamic: StrokeResult) -> tuple[float, float]:
    """Upper confidence bounds of the dynamic/paper ratio of RMSE and of onset peak in one cell."""
    return (ratio_upper_bound(dynamic.stroke_rmse_n, paper.stroke_rmse_n),
            ratio_upper_bound(dynamic.stroke_peak_pct, paper.stroke_peak_pct))


def recommendation(results: dict[Cell, dict[str, StrokeResult]]) -> Recommendation:
    """Per (support, speed) cell: dynamic where it beats the paper's with confidence on the held-out
    strokes of that cell — the upper 95 % bound (:func:`ratio_upper_bound`) of its RMSE and of its
    onset peak, each over the paper's, below 1 — the paper's lines elsewhere."""
    if any("dynamic" not in by_name for by_name in results.values()):
        return Recommendation((), False, "the model has no dynamic compensation")
    cells, lost = [], []
    for cell, by_name in results.items():
        rmse_bound, peak_bound = cell_bounds(by_name["paper"], by_name["dynamic"])
        wins = rmse_bound < 1.0 and peak_bound < 1.0
        cells.append((cell[0], cell[1], wins))
        if not wins:
            lost.append(f"{_label(cell)} (RMSE ≤ {rmse_bound:.2f}×, onset peak ≤ {peak_bound:.2f}×)")
    rule = (f"the {100 * CONFIDENCE:.0f} % upper bound of its RMSE and onset peak over the paper's, "
            "from paired held-out strokes, below 1")
    if not lost:
        why = f"the dynamic compensation beats the paper's in all {len(cells)} cells ({rule})"
    else:
        why = (f"dynamic in {len(cells) - len(lost)} of {len(cells)} cells ({rule}); the paper's lines in: "
               f"{'; '.join(lost)}")
    return Recommendation(tuple(cells), not lost, why)
