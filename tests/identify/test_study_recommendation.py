"""The per-cell recommendation rule (docs/dynamic_compensation.md, "Which compensation"), by hand."""

from __future__ import annotations

import math

import pytest

from bowden.identify.study_fit import StrokeResult
from bowden.identify.study_recommendation import ratio_upper_bound, recommendation


def test_the_ratio_bound_is_students_on_the_paired_stroke_differences() -> None:
    # d = (-1, -1, -2): mean -4/3, s_d = sqrt(1/3), s_d/sqrt(3) = 1/3, t(0.95, 2) = 2.919986;
    # mean paper 10/3: bound 1 + (-4/3 + 2.919986/3) / (10/3) = 1 + (-4 + 2.919986) / 10.
    assert ratio_upper_bound((1.0, 2.0, 3.0), (2.0, 3.0, 5.0)) == pytest.approx(0.8919986, abs=1e-6)
    assert ratio_upper_bound((1.0, 2.0, 3.0), (2.0, 3.0, 5.0), confidence=0.5) == pytest.approx(0.6)
    # Nothing is shown by one stroke, unpaired strokes or a paper's value that is not positive.
    assert ratio_upper_bound((1.0,), (2.0,)) == math.inf
    assert ratio_upper_bound((1.0, 2.0), (2.0, 3.0, 4.0)) == math.inf
    assert ratio_upper_bound((1.0, 2.0), (-2.0, 1.0)) == math.inf


def test_a_cell_won_on_average_but_not_with_confidence_goes_to_the_papers_lines() -> None:
    # The dynamic compensation's mean RMSE (9.5 N) is below the paper's (10 N) on the six strokes,
    # but its strokes scatter by ±4 N about the paper's: the upper bound of the ratio is above 1.
    results = {("50", "V2"): {
        "paper": StrokeResult(10.0, 40.0, (10.0,) * 6, (40.0,) * 6),
        "dynamic": StrokeResult(9.5, 20.0, (6.0, 14.0, 5.0, 13.0, 7.0, 12.0), (20.0,) * 6),
    }}
    choice = recommendation(results)
    assert choice.cells == (("50", "V2", False),)
    rmse_bound = ratio_upper_bound((6.0, 14.0, 5.0, 13.0, 7.0, 12.0), (10.0,) * 6)
    assert rmse_bound > 1.0
    assert f"50 % V2 (RMSE ≤ {rmse_bound:.2f}×, onset peak ≤ 0.50×)" in choice.why
    # The same mean with the strokes close together: a win.
    results["50", "V2"]["dynamic"] = StrokeResult(9.5, 20.0, (9.4, 9.6, 9.5, 9.5, 9.4, 9.6), (20.0,) * 6)
    assert recommendation(results).cells == (("50", "V2", True),)
