"""glmm.R (written by ``bowden analyze --export``) refits the report's GLMMs in R: same estimates to 1e-4.

R and its packages come from Debian (.ci/run installs r-base-core, r-cran-nlme, r-cran-lme4,
r-cran-glmmtmb, r-cran-car, r-cran-emmeans).
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from tests.study.reduced_study import AnalyzeExport

from bowden.contracts import CONDITIONS, SPEEDS
from bowden.stats import analyse_outcome, estimated_marginal_means
from bowden.study.statistics import outcome_data

RSCRIPT = shutil.which("Rscript")
pytestmark = pytest.mark.skipif(RSCRIPT is None, reason="Rscript missing: .ci/run installs Debian's R")
RTOL = 1e-4


@pytest.fixture(scope="module")
def refitted(small_study_export: AnalyzeExport) -> Path:
    # bowden analyze STUDY --export DIR --format csv of the shared reduced study (tests/share/conftest.py)
    assert small_study_export.code == 0
    tables = small_study_export.tables
    assert RSCRIPT is not None
    run = subprocess.run([RSCRIPT, str(tables / "glmm.R")], capture_output=True, text=True, timeout=280,
                         check=False)
    assert run.returncode == 0, run.stderr
    assert "refitted 26 models; skipped 0" in run.stdout
    return tables


def _ours(tables: Path, measure: str, phase: str):  # type: ignore[no-untyped-def]
    outcomes = pd.read_csv(tables / "outcomes.csv")
    return analyse_outcome(outcome_data(outcomes, measure, phase), measure)


def test_every_report_model_has_r_coefficients_equal_to_bowden(refitted: Path) -> None:
    r = pd.read_csv(refitted / "glmm_pql_reml_coefficients.csv")
    models = r[["measure", "phase"]].drop_duplicates()
    assert len(models) == 26  # elevation RMSE, SPARC; iEMG of 8 muscles in 3 phases
    for measure, phase in models.itertuples(index=False, name=None):
        fit = _ours(refitted, measure, phase).fit
        theirs = r[(r["measure"] == measure) & (r["phase"] == phase)]
        np.testing.assert_allclose(fit.coef.to_numpy(), theirs["estimate"], rtol=RTOL, atol=1e-8,
                                   err_msg=f"{measure} {phase}")
        np.testing.assert_allclose(fit.se.to_numpy(), theirs["se"], rtol=RTOL, err_msg=f"{measure} {phase}")


def test_r_type_iii_tests_and_marginal_means_equal_the_report(refitted: Path) -> None:
    type3 = pd.read_csv(refitted / "glmm_pql_reml_type3.csv")
    emm = pd.read_csv(refitted / "glmm_pql_reml_emmeans.csv")
    for measure, phase in (("elevation_rmse_rad", "entire"), ("sparc", "entire"),
                           ("iemg_anterior_deltoid", "raising"), ("iemg_trapezius", "lowering")):
        analysis = _ours(refitted, measure, phase)
        theirs = type3[(type3["measure"] == measure) & (type3["phase"] == phase)].set_index("term")
        for term in ("condition", "speed", "condition:speed"):
            assert analysis.tests.loc[term, "chisq"] == pytest.approx(theirs.loc[term, "chisq"], rel=RTOL)
        means = emm[(emm["measure"] == measure) & (emm["phase"] == phase)]
        for factor, levels in (("condition", CONDITIONS), ("speed", SPEEDS)):
            ours = estimated_marginal_means(analysis.fit, factor)
            expected = means[means["factor"] == factor].set_index("level").loc[list(ours[factor])]
            assert list(ours[factor]) == list(levels)
            np.testing.assert_allclose(ours["mean"].to_numpy(), expected["mean"], rtol=RTOL)
            np.testing.assert_allclose(ours["se"].to_numpy(), expected["se"], rtol=RTOL)
