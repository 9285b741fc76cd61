"""Degenerate data is a recorded, named failure — never a crash of the statistics stage."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from bowden.errors import FitError, OutcomeTableError
from bowden.stats import fit_gamma_glmm
from bowden.stats.friedman import friedman_test
from bowden.study.statistics import study_statistics

CONDITIONS = ("no_suit", "pretension", "support_25", "support_50")


def outcome_rows(measure: str, values) -> list[dict[str, object]]:  # type: ignore[no-untyped-def]
    cells = [(f"P{p}", c, s) for p in range(6) for c in CONDITIONS for s in ("V1", "V2", "V3")]
    return [
        {"participant": p, "condition": c, "speed": s, "phase": "entire", "measure": measure, "value": v}
        for (p, c, s), v in zip(cells, values, strict=True)
    ]


def test_a_constant_outcome_is_a_fit_error_that_says_so() -> None:
    data = pd.DataFrame(outcome_rows("x", [2.0] * 72))
    with pytest.raises(FitError, match="every value is 2: a constant outcome"):
        fit_gamma_glmm(data)


def test_the_statistics_stage_names_the_constant_outcome_and_goes_on() -> None:
    rng = np.random.default_rng(0)
    sparc = -2.0 + 0.1 * rng.normal(size=72)
    rows = outcome_rows("elevation_rmse_rad", [0.1] * 72) + outcome_rows("sparc", sparc)
    stats = study_statistics(pd.DataFrame(rows), pd.DataFrame())
    named = [f for f in stats.failures if "constant outcome" in f]
    assert len(named) == 1 and named[0].startswith("RMSE (deg): every value is")
    assert len(stats.kinematics) == 1  # SPARC was still fitted


def test_a_duplicated_friedman_row_names_its_participant_only() -> None:
    rows = [{"participant": f"P{p}", "condition": c, "value": float((p + i) % 5)}
            for p in range(5) for i, c in enumerate(CONDITIONS)]
    rows.append({"participant": "P0", "condition": "pretension", "value": 3.0})  # the first one, twice
    with pytest.raises(OutcomeTableError, match=r"\(1 here\); check participant\(s\) \['P0'\]$"):
        friedman_test(pd.DataFrame(rows))
