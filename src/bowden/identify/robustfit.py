"""Robust linear regression equal to MATLAB's ``robustfit`` with its default bisquare weights.

The paper fitted its two compensation lines with MATLAB R2023a ``robustfit`` (section "Model
identification"). This module computes the same numbers, following MathWorks' documented algorithm
(``robustfit`` reference page, "Algorithms"; DuMouchel & O'Brien 1989; Street, Carroll & Ruppert
1988) as MATLAB documents it (robustfit, Statistics and Machine Learning Toolbox):

1. Ordinary least squares through a column-pivoted QR factorisation of X = [1, x].
2. Leverage h = min(0.9999, rowsum(Q²)) of that OLS fit; residuals are adjusted as r/sqrt(1 − h).
3. Scale s = median of the sorted |adjusted residuals| after dropping the p − 1 smallest, / 0.6745
   (a MAD about zero, not about the median), floored at 1e-6·std(y).
4. Bisquare weights w = (1 − u²)² for |u| < 1, u = r_adj / (4.685·s); weighted least squares; repeat
   (at most 50 times) until every |b − b₀| ≤ sqrt(eps)·max(|b|, |b₀|).
5. Standard errors: s_final²·(XᵀX)⁻¹ from the OLS R factor, where s_final is the larger of the robust
   sigma (Street et al. with O'Brien's leverage term) and a weighted mean of it and the OLS sigma.

It also reports two coefficients of determination (MATLAB fitlm with 'RobustOpts', and OLS),
labelled, because MATLAB's ``robustfit`` returns none and the paper's 0.9940/0.9906 most likely
came from ``fitlm`` with ``'RobustOpts','on'``:

* ``r_squared_fitlm_robust`` = SSR / (SSR + dfe·s_final²), SSR = Σ(ŷ − ȳ)² — what ``fitlm`` prints;
* ``r_squared_ols`` = the ordinary least-squares R², equal to corr(x, y)² for one predictor.

statsmodels' ``RLM(..., TukeyBiweight())`` is a different estimator (no leverage adjustment, a
median-centred MAD re-estimated each iteration, deviance-based convergence, sandwich covariance);
``tests/identify/test_robustfit_statsmodels.py`` shows where the numbers part.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bowden.errors import FitError

BISQUARE_TUNE = 4.685
"""MATLAB's default bisquare tuning constant (95 % efficiency at the normal model)."""
MAD_NORMALISER = 0.6745
"""MATLAB's constant (not norm.ppf(0.75) = 0.67449, which statsmodels uses)."""
MAX_LEVERAGE = 0.9999
MAX_ITERATIONS = 50

_EPS = float(np.finfo(np.float64).eps)
_CONVERGENCE = math.sqrt(_EPS)  # MATLAB: D = sqrt(eps(class(X)))
_DERIVATIVE_STEP = 1e-4  # statrobustsigma's central difference step on the standardised residual


@dataclass(frozen=True, eq=False)
class RobustFit:
    """Result of :func:`robustfit` (names follow MATLAB's ``stats`` structure, in words).

    Attributes
    ----------
    coefficients
        b, shape (p,), intercept first (units of y, then y per unit of each predictor).
    standard_errors
        MATLAB ``stats.se``, shape (p,).
    covariance
        MATLAB ``stats.covb``, shape (p, p).
    t_statistics, p_values
        b / se and the two-sided p-value from Student's t with ``dfe`` degrees of freedom.
    ols_scale
        ``stats.ols_s``: root mean square error of the ordinary least-squares fit.
    robust_scale
        ``stats.robust_s``: robust sigma of the final fit.
    mad_scale
        ``stats.mad_s``: the MAD scale of the final adjusted residuals.
    scale
        ``stats.s``: the sigma used for the standard errors.
    residuals
        y − X·b, shape (n,).
    weights
        ``stats.w``: bisquare weights of the last iteration, shape (n,).
    leverage
        ``stats.h``: leverage of the OLS fit, capped at 0.9999, shape (n,).
    dfe
        Residual degrees of freedom n − rank.
    iterations
        Weighted least-squares iterations performed.
    converged
        False when the iteration limit stopped the loop (MATLAB warns in that case).
    r_squared_ols
        Ordinary least-squares R² (= corr(x, y)² for one predictor).
    r_squared_fitlm_robust
        R² as MATLAB ``fitlm(..., 'RobustOpts', 'on')`` reports it: SSR / (SSR + dfe·scale²).
    """

    coefficients: NDArray[np.float64]
    standard_errors: NDArray[np.float64]
    covariance: NDArray[np.float64]
    t_statistics: NDArray[np.float64]
    p_values: NDArray[np.float64]
    ols_scale: float
    robust_scale: float
    mad_scale: float
    scale: float
    residuals: NDArray[np.float64]
    weights: NDArray[np.float64]
    leverage: NDArray[np.float64]
    dfe: int
    iterations: int
    converged: bool
    r_squared_ols: float
    r_squared_fitlm_robust: float

    @property
    def n(self) -> int:
        """Number of observations."""
        return int(self.residuals.shape[0])

    @property
    def intercept(self) -> float:
        """b[0], in units of y."""
        return float(self.coefficients[0])

    @property
    def slope(self) -> float:
        """b[1] of a one-predictor fit, in units of y per unit of x."""
        if self.coefficients.shape[0] != 2:
            raise FitError(
                f"slope is defined for one predictor; this fit has {self.coefficients.shape[0] - 1}"
            )
        return float(self.coefficients[1])

    @property
    def intercept_se(self) -> float:
        """Standard error of the intercept."""
        return float(self.standard_errors[0])

    @property
    def slope_se(self) -> float:
        """Standard error of the slope of a one-predictor fit."""
        if self.standard_errors.shape[0] != 2:
            raise FitError("slope_se is defined for one predictor")
        return float(self.standard_errors[1])


def bisquare_weight(u: NDArray[np.float64]) -> NDArray[np.float64]:
    """Tukey's bisquare weight (1 − u²)² for |u| < 1, else 0 (u already divided by tune·s)."""
    inside = np.abs(u) < 1.0
    return np.where(inside, (1.0 - u * u) ** 2, 0.0)


def mad_sigma(adjusted_residuals: NDArray[np.float64], rank: int) -> float:
    """MATLAB's ``madsigma``: the median of |r| after dropping the rank − 1 smallest, / 0.6745.

    The p − 1 smallest absolute residuals are dropped because a fit with p coefficients can make
    p − 1 of them (near) zero by construction (O'Brien; Street et al. below eq. 8). The MAD is taken
    about zero, not about the median.
    """
    sorted_abs = np.sort(np.abs(adjusted_residuals))
    return float(np.median(sorted_abs[max(1, rank) - 1 :])) / MAD_NORMALISER


def robust_sigma(
    adjusted_residuals: NDArray[np.float64],
    rank: int,
    scale: float,
    tune: float,
    leverage: NDArray[np.float64],
) -> float:
    """Final robust sigma (MATLAB ``statrobustsigma``; Street, Carroll & Ruppert 1988, eq. 8).

    sigma = K·sqrt(m2)·s·t / m1 with u = r_adj/(s·t), ψ(u) = u·w(u), m1 = mean ψ'(u) (central
    difference, step 1e-4, as MATLAB), m2 = Σ(1 − h)·ψ(u)² / (n − p) (O'Brien's leverage term) and
    K = 1 + (p/n)·(1 − m1)/m1 (Huber's correction).
    """
    n = adjusted_residuals.shape[0]
    st = scale * tune
    u = adjusted_residuals / st
    psi = u * bisquare_weight(u)
    below = u - _DERIVATIVE_STEP
    above = u + _DERIVATIVE_STEP
    dpsi = (above * bisquare_weight(above) - below * bisquare_weight(below)) / (2.0 * _DERIVATIVE_STEP)
    m1 = float(np.mean(dpsi))
    m2 = float(np.sum((1.0 - leverage) * psi * psi)) / (n - rank)
    k = 1.0 + (rank / n) * (1.0 - m1) / m1
    return float(k * math.sqrt(m2) * st / m1)


def _pivoted_qr(
    design: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.intp], int]:
    """Economy QR with column pivoting and MATLAB's rank rule |R_ii| > |R_11|·max(n, p)·eps."""
    from scipy.linalg import qr  # here, as scipy.stats below: `bowden --help` reads this package

    q, r, perm = qr(design, mode="economic", pivoting=True)
    n, p = design.shape
    diagonal = np.abs(np.diag(r))
    tolerance = (diagonal[0] if diagonal.size else 0.0) * max(n, p) * _EPS
    rank = int(np.sum(diagonal > tolerance))
    return q, r, perm, rank


def _weighted_least_squares(
    y: NDArray[np.float64], design: NDArray[np.float64], weights: NDArray[np.float64]
) -> tuple[NDArray[np.float64], int]:
    """Weighted LS through QR of sqrt(w)·X; a rank-deficient system gets its basic solution."""
    from scipy.linalg import solve_triangular

    root_w = np.sqrt(weights)
    q, r, perm, rank = _pivoted_qr(design * root_w[:, None])
    coefficients = np.zeros(design.shape[1])
    if rank > 0:
        qty = q[:, :rank].T @ (y * root_w)
        coefficients[perm[:rank]] = solve_triangular(r[:rank, :rank], qty)
    return coefficients, rank


def _as_design(x: ArrayLike, y: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    predictors = np.asarray(x, dtype=np.float64)
    response = np.asarray(y, dtype=np.float64)
    if predictors.ndim == 1:
        predictors = predictors[:, None]
    if predictors.ndim != 2 or response.ndim != 1:
        raise FitError(
            f"robustfit needs x of shape (n,) or (n, p) and y of shape (n,), "
            f"got {np.shape(x)} and {np.shape(y)}"
        )
    if predictors.shape[0] != response.shape[0]:
        raise FitError(f"x has {predictors.shape[0]} rows but y has {response.shape[0]}")
    bad = ~np.isfinite(response) | ~np.all(np.isfinite(predictors), axis=1)
    if np.any(bad):
        first = int(np.flatnonzero(bad)[0])
        raise FitError(
            f"robustfit got {int(bad.sum())} non-finite value(s), first at index {first}; "
            "remove or interpolate them first"
        )
    n = predictors.shape[0]
    design = np.hstack([np.ones((n, 1)), predictors])
    if n <= design.shape[1]:
        raise FitError(
            f"robustfit needs more observations than coefficients: {n} observation(s) "
            f"for {design.shape[1]} coefficients"
        )
    return design, response


def robustfit(
    x: ArrayLike,
    y: ArrayLike,
    *,
    tune: float = BISQUARE_TUNE,
    max_iterations: int = MAX_ITERATIONS,
) -> RobustFit:
    """Robust regression of y on x with an intercept, as MATLAB ``robustfit(x, y)``.

    Parameters
    ----------
    x
        Predictor(s), shape (n,) or (n, p); a column of ones is added (do not include one).
    y
        Response, shape (n,).
    tune
        Bisquare tuning constant (MATLAB default 4.685).
    max_iterations
        Iteration limit of the reweighting loop (MATLAB: 50).

    Returns
    -------
    RobustFit
        Coefficients (intercept first), standard errors, scales, weights and both R².

    Raises
    ------
    FitError
        Non-finite input, too few observations, or a degenerate design (e.g. constant x).

    Notes
    -----
    Algorithm: MathWorks ``robustfit`` documentation ("Algorithms"), DuMouchel & O'Brien (1989),
    Street, Carroll & Ruppert (1988), Am Stat 42:152. MATLAB's public parity case (x = 1..10,
    y = 3.1 5.2 6.9 9.1 11 12.9 15.2 17.1 19 5) gives b = [1.08223788958791, 1.9947584179332].
    """
    if not (tune > 0.0 and math.isfinite(tune)):
        raise FitError(f"tune must be a positive finite number, got {tune!r}")
    if max_iterations < 1:
        raise FitError(f"max_iterations must be at least 1, got {max_iterations!r}")
    from scipy.linalg import solve_triangular

    design, response = _as_design(x, y)
    n, p = design.shape

    q, r, perm, rank = _pivoted_qr(design)
    if rank < p:
        raise FitError(
            f"the design matrix has rank {rank} < {p}: a predictor is constant or collinear "
            "(e.g. every sample at the same tension), so no line can be fitted"
        )
    r_factor = r[:p, :p]
    coefficients = np.zeros(p)
    coefficients[perm] = solve_triangular(r_factor, q.T @ response)
    ols_coefficients = coefficients.copy()

    # Leverage of the OLS fit: rows of E = X·R⁻¹ (in pivoted column order) equal rows of Q.
    e = solve_triangular(r_factor, design[:, perm].T, trans="T").T
    leverage = np.minimum(MAX_LEVERAGE, np.sum(e * e, axis=1))
    adjust = 1.0 / np.sqrt(1.0 - leverage)

    dfe = n - rank
    ols_residuals = response - design @ coefficients
    ols_scale = float(np.linalg.norm(ols_residuals)) / math.sqrt(dfe)

    # Never let the scale collapse on a (near) perfect fit (MATLAB's tiny_s).
    tiny_scale = 1e-6 * float(np.std(response, ddof=1))
    if tiny_scale == 0.0:
        tiny_scale = 1.0

    previous = np.zeros(p)
    weights = np.ones(n)
    weighted_rank = rank
    iterations = 0
    converged = True
    while iterations == 0 or np.any(
        np.abs(coefficients - previous) > _CONVERGENCE * np.maximum(np.abs(coefficients), np.abs(previous))
    ):
        iterations += 1
        if iterations > max_iterations:
            iterations = max_iterations
            converged = False
            break
        adjusted = (response - design @ coefficients) * adjust
        scale = mad_sigma(adjusted, weighted_rank)
        weights = bisquare_weight(adjusted / (max(scale, tiny_scale) * tune))
        previous = coefficients
        coefficients, weighted_rank = _weighted_least_squares(response, design, weights)

    residuals = response - design @ coefficients
    adjusted = residuals * adjust
    mad_scale = mad_sigma(adjusted, rank)
    if np.all((weights < _CONVERGENCE) | (weights > 1.0 - _CONVERGENCE)):
        # Weights all 0 or 1: this is OLS on a subset, so use that subset's RMSE (as MATLAB).
        included = weights > 1.0 - _CONVERGENCE
        robust_scale = float(np.linalg.norm(residuals[included])) / math.sqrt(
            max(int(included.sum()) - rank, 1)
        )
    else:
        robust_scale = robust_sigma(adjusted, rank, max(mad_scale, tiny_scale), tune, leverage)
    # Shrink towards the OLS sigma when the robust one is smaller, never below the robust one.
    scale_final = max(
        robust_scale,
        math.sqrt((ols_scale**2 * rank**2 + robust_scale**2 * n) / (rank**2 + n)),
    )

    r_inverse = solve_triangular(r_factor, np.eye(p))
    pivoted_cov = (r_inverse @ r_inverse.T) * scale_final**2
    covariance = np.empty((p, p))
    covariance[np.ix_(perm, perm)] = pivoted_cov
    standard_errors = np.sqrt(np.maximum(_EPS, np.diag(covariance)))
    t_statistics = coefficients / standard_errors
    # Imported here: bowden.identify imports this module eagerly (robustfit shares its name), and the
    # command line's parser, which reads bowden.identify.settings, should not pay for scipy.stats.
    from scipy.stats import t as student_t

    p_values = 2.0 * student_t.sf(np.abs(t_statistics), dfe)

    fitted = design @ coefficients
    ssr = float(np.sum((fitted - response.mean()) ** 2))
    denominator = ssr + dfe * scale_final**2
    r_squared_robust = ssr / denominator if denominator > 0.0 else 1.0
    sst = float(np.sum((response - response.mean()) ** 2))
    sse_ols = float(np.sum((response - design @ ols_coefficients) ** 2))
    r_squared_ols = 1.0 - sse_ols / sst if sst > 0.0 else 1.0

    return RobustFit(
        coefficients=coefficients,
        standard_errors=standard_errors,
        covariance=covariance,
        t_statistics=t_statistics,
        p_values=p_values,
        ols_scale=ols_scale,
        robust_scale=robust_scale,
        mad_scale=mad_scale,
        scale=scale_final,
        residuals=residuals,
        weights=weights,
        leverage=leverage,
        dfe=dfe,
        iterations=iterations,
        converged=converged,
        r_squared_ols=r_squared_ols,
        r_squared_fitlm_robust=r_squared_robust,
    )
