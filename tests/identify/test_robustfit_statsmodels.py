"""Where statsmodels' RLM(TukeyBiweight) differs from MATLAB's robustfit, and why.

Both are bisquare M-estimators with tuning constant 4.685 started from OLS, yet they converge to
different lines. The test pins the difference down: an IRLS that makes statsmodels' three choices
reproduces RLM to rounding, while robustfit differs from it by far more than rounding:

1. no leverage adjustment of the residuals (MATLAB divides them by sqrt(1 − h));
2. scale = median |r| / norm.ppf(0.75), re-estimated from every new fit's residuals, without dropping
   the p − 1 smallest (statsmodels 0.14+ uses ``mad(resid, center=0)``, i.e. about zero like MATLAB,
   not about the median as older statsmodels versions did);
3. standard errors from Huber's H1 sandwich instead of MATLAB's s²·(XᵀX)⁻¹ with s shrunk towards the
   OLS sigma.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats
import statsmodels.api as sm
from statsmodels.robust.norms import TukeyBiweight

from bowden.identify import robustfit

from .test_robustfit import PARITY_B, PARITY_X, PARITY_Y, contaminated_line

TUNE = 4.685


def statsmodels_style_irls(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bisquare IRLS with statsmodels' choices (1) and (2), iterated to its fixed point."""
    design = np.column_stack([np.ones_like(x), x])
    normaliser = scipy.stats.norm.ppf(0.75)
    b = np.linalg.lstsq(design, y, rcond=None)[0]
    scale = np.median(np.abs(y - design @ b)) / normaliser
    for _ in range(1000):
        u = (y - design @ b) / (scale * TUNE)
        root_w = np.sqrt(np.where(np.abs(u) < 1.0, (1.0 - u * u) ** 2, 0.0))
        new_b = np.linalg.lstsq(design * root_w[:, None], y * root_w, rcond=None)[0]
        scale = np.median(np.abs(y - design @ new_b)) / normaliser
        if np.all(np.abs(new_b - b) <= 1e-14 * np.abs(new_b)):
            return new_b
        b = new_b
    return b


def rlm(x: np.ndarray, y: np.ndarray) -> sm.regression.linear_model.RegressionResults:
    model = sm.RLM(y, sm.add_constant(x), M=TukeyBiweight(c=TUNE))
    return model.fit(tol=1e-15, maxiter=1000)


@pytest.mark.parametrize("case", ["parity", "bench0", "bench1"])
def test_rlm_is_a_different_estimator_explained_by_its_scale_and_leverage_choices(case: str) -> None:
    x, y = (PARITY_X, PARITY_Y) if case == "parity" else contaminated_line(int(case[-1]))
    matlab = robustfit(x, y)
    statsmodels_fit = rlm(x, y)
    # statsmodels' choices, transcribed independently, reproduce RLM to rounding ...
    assert statsmodels_fit.params == pytest.approx(statsmodels_style_irls(x, y), rel=1e-10, abs=1e-13)
    # ... and differ from MATLAB's robustfit by much more than rounding.
    difference = np.abs(statsmodels_fit.params - matlab.coefficients)
    assert np.max(difference / np.abs(matlab.coefficients)) > 1e-6


def test_rlm_misses_matlab_parity_case() -> None:
    statsmodels_fit = rlm(PARITY_X, PARITY_Y)
    # 2.5e-3 away from MATLAB's published intercept; robustfit matches it to 1e-10.
    assert abs(statsmodels_fit.params[0] - PARITY_B[0]) > 1e-3
    assert robustfit(PARITY_X, PARITY_Y).intercept == pytest.approx(PARITY_B[0], abs=1e-10)


def test_standard_errors_differ_in_kind() -> None:
    # On ten points MATLAB shrinks the robust sigma towards the OLS sigma (4.59, inflated by the
    # outlier), while RLM's H1 sandwich does not: the standard errors differ by an order of magnitude.
    matlab = robustfit(PARITY_X, PARITY_Y)
    statsmodels_fit = rlm(PARITY_X, PARITY_Y)
    assert matlab.scale > 10 * statsmodels_fit.scale
    assert np.all(matlab.standard_errors > 10 * statsmodels_fit.bse)
    # With plenty of data both describe the same uncertainty to within a factor of two.
    x, y = contaminated_line(0, n=2000)
    ratio = robustfit(x, y).standard_errors / rlm(x, y).bse
    assert np.all((ratio > 0.5) & (ratio < 2.0))
