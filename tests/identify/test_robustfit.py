"""robustfit against MATLAB's published parity case and an independent transcription of its algorithm."""

from __future__ import annotations

import math
import statistics

import numpy as np
import pytest
import scipy.stats

from bowden.errors import FitError
from bowden.identify import robustfit

# MATLAB's public parity case (MathWorks robustfit documentation): robustfit(x, y), default bisquare.
PARITY_X = np.arange(1.0, 11.0)
PARITY_Y = np.array([3.1, 5.2, 6.9, 9.1, 11.0, 12.9, 15.2, 17.1, 19.0, 5.0])
PARITY_B = (1.08223788958791, 1.9947584179332)
PARITY_OLS_S = 4.58673317428878


def independent_robustfit(x: np.ndarray, y: np.ndarray, tune: float = 4.685) -> dict[str, object]:
    """A plain transcription of MathWorks' documented robustfit algorithm.

    Deliberately computed differently from the package: normal equations instead of QR, the hat
    matrix for the leverage, statistics.median on Python lists, explicit loops for the weights.
    """
    n = len(y)
    design = np.column_stack([np.ones(n), x])
    p = design.shape[1]
    xtx_inv = np.linalg.inv(design.T @ design)
    b = xtx_inv @ design.T @ y
    ols_b = b.copy()
    hat = design @ xtx_inv @ design.T
    h = [min(0.9999, hat[i, i]) for i in range(n)]
    adj = [1.0 / math.sqrt(1.0 - hi) for hi in h]
    dfe = n - p
    ols_s = math.sqrt(sum((y[i] - design[i] @ b) ** 2 for i in range(n)) / dfe)
    tiny = 1e-6 * statistics.stdev(y.tolist()) or 1.0

    def madsig(radj: list[float]) -> float:
        ordered = sorted(abs(v) for v in radj)
        return statistics.median(ordered[p - 1 :]) / 0.6745

    def bisq(u: float) -> float:
        return (1.0 - u * u) ** 2 if abs(u) < 1.0 else 0.0

    b0 = np.zeros(p)
    w = [1.0] * n
    iterations = 0
    while iterations == 0 or any(
        abs(b[j] - b0[j]) > math.sqrt(np.finfo(float).eps) * max(abs(b[j]), abs(b0[j])) for j in range(p)
    ):
        iterations += 1
        assert iterations <= 50
        radj = [(y[i] - design[i] @ b) * adj[i] for i in range(n)]
        s = max(madsig(radj), tiny)
        w = [bisq(r / (s * tune)) for r in radj]
        wd = design * np.array(w)[:, None]
        b0 = b
        b = np.linalg.solve(design.T @ wd, wd.T @ y)

    radj = [(y[i] - design[i] @ b) * adj[i] for i in range(n)]
    mad_s = madsig(radj)
    st = max(mad_s, tiny) * tune
    u = [r / st for r in radj]
    delta = 1e-4
    dpsi = [((ui + delta) * bisq(ui + delta) - (ui - delta) * bisq(ui - delta)) / (2 * delta) for ui in u]
    m1 = sum(dpsi) / n
    m2 = sum((1 - h[i]) * (u[i] * bisq(u[i])) ** 2 for i in range(n)) / (n - p)
    k = 1 + (p / n) * (1 - m1) / m1
    robust_s = k * math.sqrt(m2) * st / m1
    sigma = max(robust_s, math.sqrt((ols_s**2 * p**2 + robust_s**2 * n) / (p**2 + n)))
    cov = xtx_inv * sigma**2
    fitted = design @ b
    ssr = float(np.sum((fitted - y.mean()) ** 2))
    return {
        "b": b,
        "ols_b": ols_b,
        "se": np.sqrt(np.diag(cov)),
        "ols_s": ols_s,
        "mad_s": mad_s,
        "robust_s": robust_s,
        "s": sigma,
        "w": np.array(w),
        "h": np.array(h),
        "iterations": iterations,
        "r2_fitlm": ssr / (ssr + dfe * sigma**2),
    }


def contaminated_line(
    seed: int, n: int = 400, outlier_fraction: float = 0.1
) -> tuple[np.ndarray, np.ndarray]:
    """A bench-like line (torque ≈ 0.05 + 0.04·tension) with gross outliers."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(5.0, 120.0, n)
    y = 0.05 + 0.04 * x + rng.normal(0.0, 0.08, n)
    bad = rng.choice(n, int(outlier_fraction * n), replace=False)
    y[bad] += rng.choice([-1.0, 1.0], bad.size) * rng.uniform(1.0, 4.0, bad.size)
    return x, y


def test_matlab_parity_case_to_1e10() -> None:
    fit = robustfit(PARITY_X, PARITY_Y)
    assert fit.coefficients == pytest.approx(PARITY_B, abs=1e-10)
    assert fit.ols_scale == pytest.approx(PARITY_OLS_S, abs=1e-10)
    # The gross outlier (x = 10, y = 5) is rejected outright; the others keep most of their weight.
    assert fit.weights[-1] == 0.0
    assert np.all(fit.weights[:-1] > 0.9)
    assert fit.converged


def test_parity_case_against_independent_transcription() -> None:
    fit = robustfit(PARITY_X, PARITY_Y)
    ref = independent_robustfit(PARITY_X, PARITY_Y)
    assert fit.coefficients == pytest.approx(ref["b"], abs=1e-12)
    assert fit.standard_errors == pytest.approx(ref["se"], rel=1e-10)
    assert fit.scale == pytest.approx(ref["s"], rel=1e-10)
    assert fit.robust_scale == pytest.approx(ref["robust_s"], rel=1e-10)
    assert fit.mad_scale == pytest.approx(ref["mad_s"], rel=1e-10)
    assert fit.iterations == ref["iterations"]


@pytest.mark.parametrize("seed", range(6))
def test_random_data_with_outliers_agrees_with_independent_transcription(seed: int) -> None:
    x, y = contaminated_line(seed)
    fit = robustfit(x, y)
    ref = independent_robustfit(x, y)
    assert fit.coefficients == pytest.approx(ref["b"], rel=1e-9, abs=1e-12)
    assert fit.standard_errors == pytest.approx(ref["se"], rel=1e-9)
    assert fit.ols_scale == pytest.approx(ref["ols_s"], rel=1e-12)
    assert fit.mad_scale == pytest.approx(ref["mad_s"], rel=1e-9)
    assert fit.robust_scale == pytest.approx(ref["robust_s"], rel=1e-9)
    assert fit.scale == pytest.approx(ref["s"], rel=1e-9)
    assert fit.weights == pytest.approx(ref["w"], abs=1e-8)
    assert fit.leverage == pytest.approx(ref["h"], rel=1e-10)
    assert fit.r_squared_fitlm_robust == pytest.approx(ref["r2_fitlm"], rel=1e-10)
    # And it actually is robust: the truth is recovered despite 10 % gross outliers.
    assert fit.slope == pytest.approx(0.04, abs=5e-4)
    assert fit.intercept == pytest.approx(0.05, abs=0.03)


def test_r_squared_definitions() -> None:
    x, y = contaminated_line(11)
    fit = robustfit(x, y)
    # OLS R² of a line is corr(x, y)², which SciPy's linregress reports as rvalue².
    assert fit.r_squared_ols == pytest.approx(scipy.stats.linregress(x, y).rvalue ** 2, rel=1e-12)
    # fitlm's robust R²: SSR / (SSR + dfe·s²), SSR about the unweighted mean of y.
    fitted = fit.intercept + fit.slope * x
    ssr = np.sum((fitted - y.mean()) ** 2)
    assert fit.r_squared_fitlm_robust == pytest.approx(ssr / (ssr + fit.dfe * fit.scale**2), rel=1e-12)
    # Outliers inflate the OLS residuals, not the robust scale: the robust R² is the higher one here.
    assert fit.r_squared_fitlm_robust > fit.r_squared_ols


def test_covariance_is_sigma_squared_times_inverse_gram() -> None:
    x, y = contaminated_line(3, n=60)
    fit = robustfit(x, y)
    design = np.column_stack([np.ones_like(x), x])
    expected = np.linalg.inv(design.T @ design) * fit.scale**2
    assert fit.covariance == pytest.approx(expected, rel=1e-10)
    assert fit.t_statistics == pytest.approx(fit.coefficients / fit.standard_errors)
    assert fit.p_values == pytest.approx(2 * scipy.stats.t.sf(np.abs(fit.t_statistics), fit.dfe))
    assert fit.dfe == 58


def test_exact_line_is_recovered_with_unit_weights() -> None:
    x = np.linspace(0.0, 100.0, 50)
    y = -0.2 + 0.037 * x
    fit = robustfit(x, y)
    assert fit.coefficients == pytest.approx([-0.2, 0.037], abs=1e-12)
    assert np.all(fit.weights == pytest.approx(1.0))
    assert fit.r_squared_ols == pytest.approx(1.0)


def test_affine_equivariance() -> None:
    # robustfit is regression- and scale-equivariant: y -> a + c·y maps b to (a + c·b0, c·b1),
    # up to the stopping rule (relative steps below sqrt(eps) ≈ 1.5e-8).
    x, y = contaminated_line(5, n=120)
    base = robustfit(x, y)
    moved = robustfit(x, 3.0 + 2.5 * y)
    assert moved.intercept == pytest.approx(3.0 + 2.5 * base.intercept, rel=1e-7)
    assert moved.slope == pytest.approx(2.5 * base.slope, rel=1e-7)
    assert moved.weights == pytest.approx(base.weights, abs=1e-6)
    assert moved.standard_errors == pytest.approx(2.5 * base.standard_errors, rel=1e-7)


def test_multiple_predictors() -> None:
    rng = np.random.default_rng(2)
    x = rng.normal(size=(200, 2))
    y = 1.0 + 2.0 * x[:, 0] - 0.5 * x[:, 1] + rng.normal(0.0, 0.1, 200)
    y[:10] += 20.0
    fit = robustfit(x, y)
    assert fit.coefficients == pytest.approx([1.0, 2.0, -0.5], abs=0.05)
    assert np.all(fit.weights[:10] == 0.0)
    with pytest.raises(FitError, match="one predictor"):
        _ = fit.slope


def test_iteration_limit_is_reported() -> None:
    fit = robustfit(PARITY_X, PARITY_Y, max_iterations=2)
    assert not fit.converged
    assert fit.iterations == 2


@pytest.mark.parametrize(
    ("x", "y", "message"),
    [
        (np.full(10, 3.0), np.arange(10.0), "rank 1"),
        (np.array([1.0, 2.0]), np.array([1.0, 2.0]), "more observations"),
        (np.array([1.0, 2.0, np.nan, 4.0]), np.arange(4.0), "non-finite"),
        (np.arange(4.0), np.arange(5.0), "rows"),
    ],
)
def test_bad_input_raises_fit_error(x: np.ndarray, y: np.ndarray, message: str) -> None:
    with pytest.raises(FitError, match=message):
        robustfit(x, y)
