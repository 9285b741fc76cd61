"""Friedman's test and MATLAB's Bonferroni multcompare (MATLAB's documentation and its popcorn example)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from bowden.errors import OutcomeTableError, ParameterError
from bowden.stats import friedman, friedman_multcompare, friedman_test

POPCORN = [
    [5.5, 4.5, 3.5],
    [5.5, 4.5, 4.0],
    [6.0, 4.0, 3.0],
    [6.5, 5.0, 4.0],
    [7.0, 5.5, 5.0],
    [7.0, 5.0, 4.5],
]


def test_popcorn_reproduces_matlab_exactly() -> None:
    res = friedman(POPCORN, 3)
    # MATLAB R2023a: [p, tbl, stats] = friedman(popcorn, 3)
    assert res.statistic == pytest.approx(13.75862068965517, rel=1e-14)
    assert res.p == pytest.approx(0.001028853354594794, rel=1e-12)
    assert res.sigma == pytest.approx(2.692582403567252, rel=1e-14)
    assert res.df == 2 and res.n_blocks == 2 and res.reps == 3
    np.testing.assert_allclose(res.mean_ranks, [8.0, 4.75, 2.25], rtol=1e-15)
    post = friedman_multcompare(res)
    np.testing.assert_allclose(post["p"], [0.682273674085708, 0.0981614544947206, 1.0], rtol=1e-12)
    assert list(zip(post["group_a"], post["group_b"], strict=True)) == [("1", "2"), ("1", "3"), ("2", "3")]
    np.testing.assert_allclose(post["difference"], [3.25, 5.75, 2.5], rtol=1e-15)
    # Bonferroni intervals: difference -+ z(1 - 0.05/6) * sigma * sqrt(2 / n).
    half = stats.norm.isf(0.05 / 6) * 2.692582403567252
    np.testing.assert_allclose(post["upper"] - post["difference"], half, rtol=1e-12)


def test_one_rep_matches_scipy_tie_corrected_friedman() -> None:
    rng = np.random.default_rng(3)
    scores = rng.integers(1, 8, size=(17, 4)).astype(float)  # Likert: many ties
    res = friedman(scores)
    ref = stats.friedmanchisquare(*scores.T)
    assert res.statistic == pytest.approx(ref.statistic, rel=1e-12)
    assert res.p == pytest.approx(ref.pvalue, rel=1e-10)


def test_tidy_table_equals_matrix_form_and_orders_conditions() -> None:
    rng = np.random.default_rng(5)
    scores = rng.integers(6, 21, size=(12, 4)).astype(float)  # Borg RPE
    names = ["support_50", "no_suit", "support_25", "pretension"]  # deliberately shuffled
    tidy = pd.DataFrame(
        [(f"P{i:02d}", c, scores[i, k]) for i in range(12) for k, c in enumerate(names)],
        columns=["participant", "condition", "value"],
    ).sample(frac=1.0, random_state=2)
    res = friedman_test(tidy)
    assert list(res.mean_ranks.index) == ["no_suit", "pretension", "support_25", "support_50"]
    order = [names.index(c) for c in res.mean_ranks.index]
    ref = friedman(scores[:, order])
    assert res.statistic == pytest.approx(ref.statistic, rel=1e-14)
    np.testing.assert_allclose(res.mean_ranks.to_numpy(), ref.mean_ranks.to_numpy())


def test_holm_is_never_above_bonferroni() -> None:
    res = friedman(np.random.default_rng(8).normal(size=(10, 5)) + np.arange(5) * 0.4)
    bonf = friedman_multcompare(res)["p"].to_numpy()
    holm = friedman_multcompare(res, correction="holm")["p"].to_numpy()
    raw = friedman_multcompare(res, correction="none")["p"].to_numpy()
    assert np.all(raw <= holm + 1e-15) and np.all(holm <= bonf + 1e-15)
    np.testing.assert_allclose(bonf, np.minimum(1.0, raw * 10))


def test_all_tied_gives_no_evidence() -> None:
    res = friedman(np.ones((5, 3)))
    assert res.statistic == 0.0 and res.p == 1.0


@pytest.mark.parametrize(
    ("data", "reps", "message"),
    [
        (np.ones((5, 1)), 1, "two columns"),
        (np.ones((5, 3)), 2, "blocks of reps=2"),
        ([[1.0, np.nan], [2.0, 3.0]], 1, "row 0, column 1"),
        (np.ones((1, 3)), 1, "two blocks"),
    ],
)
def test_bad_matrices_are_rejected(data: object, reps: int, message: str) -> None:
    with pytest.raises(OutcomeTableError, match=message):
        friedman(data, reps)  # type: ignore[arg-type]


def test_incomplete_participant_is_named() -> None:
    tidy = pd.DataFrame(
        {
            "participant": ["a", "a", "b"],
            "condition": ["no_suit", "pretension", "no_suit"],
            "value": [1.0, 2.0, 3.0],
        }
    )
    with pytest.raises(OutcomeTableError, match=r"\['b'\]"):
        friedman_test(tidy)


def test_parameters_are_validated() -> None:
    with pytest.raises(ParameterError):
        friedman(POPCORN, 0)
    with pytest.raises(ParameterError):
        friedman_multcompare(friedman(POPCORN, 3), alpha=1.5)
