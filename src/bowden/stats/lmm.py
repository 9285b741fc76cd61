"""Linear mixed model with one random intercept per participant and homoscedastic errors.

``z = X beta + b[group] + e``, ``b ~ N(0, sigma_b^2)``, ``e ~ N(0, sigma^2)``. This is the pseudo-model
of the gamma/log PQL step (its working weights are all one), fitted by REML or ML. With
``gamma = sigma_b^2 / sigma^2`` the marginal covariance of participant i is
``sigma^2 (I + gamma 1 1')``, whose inverse and determinant are closed form
(``I - gamma / (1 + n_i gamma) 1 1'``, ``1 + n_i gamma``), so every quantity reduces to per-participant
sums and the profiled (restricted) likelihood is a smooth function of ``log gamma`` alone
(Harville 1977, J Am Stat Assoc 72:320; Pinheiro & Bates 2000, Mixed-Effects Models in S, ch. 2).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy import optimize

from bowden.errors import FitError
from bowden.stats.design import FloatArray, IntArray

LmmMethod = Literal["REML", "ML"]

# Search range of log(sigma_b^2 / sigma^2); below the lower end the variance is reported as zero.
_LOG_RATIO_BOUNDS = (-30.0, 12.0)


@dataclass(frozen=True)
class GroupSums:
    """Sufficient statistics of X per participant (they do not change between PQL iterations)."""

    n: FloatArray  # rows per participant, (m,)
    xs: FloatArray  # sum of X rows per participant, (m, p)
    xtx: FloatArray  # X'X, (p, p)

    @classmethod
    def of(cls, x: FloatArray, group: IntArray, n_groups: int) -> GroupSums:
        n = np.bincount(group, minlength=n_groups).astype(float)
        xs = np.zeros((n_groups, x.shape[1]))
        np.add.at(xs, group, x)
        return cls(n=n, xs=xs, xtx=x.T @ x)


@dataclass(frozen=True)
class LmmFit:
    """Result of :func:`fit_random_intercept_lmm`."""

    beta: FloatArray
    vcov: FloatArray  # sigma^2 (X' V^-1 X)^-1, V = I + gamma Z Z'
    sigma2: float  # residual variance
    participant_var: float  # sigma_b^2
    random_effects: FloatArray  # BLUPs, (m,)
    loglik: float  # (restricted) log-likelihood at the optimum
    at_boundary: bool  # participant variance estimated as zero


def _profile(
    log_ratio: float, sums: GroupSums, xtz: FloatArray, zs: FloatArray, ztz: float, n_obs: int, reml: bool
) -> tuple[float, FloatArray, FloatArray, float, float]:
    """Profiled -2 log-likelihood (constants dropped) and the pieces needed afterwards."""
    ratio = np.exp(log_ratio)
    d = ratio / (1.0 + sums.n * ratio)
    a = sums.xtx - (sums.xs * d[:, None]).T @ sums.xs
    c = xtz - sums.xs.T @ (d * zs)
    chol = np.linalg.cholesky(a)
    beta = np.linalg.solve(a, c)
    quad = ztz - float(np.sum(d * zs * zs)) - float(c @ beta)
    logdet_v = float(np.sum(np.log1p(sums.n * ratio)))
    p = a.shape[0]
    dof = n_obs - p if reml else n_obs
    sigma2 = quad / dof
    objective = dof * np.log(sigma2) + logdet_v
    if reml:
        objective += 2.0 * float(np.sum(np.log(np.diag(chol))))
    return float(objective), beta, a, sigma2, float(logdet_v)


def _profile_slope(
    log_ratio: float, sums: GroupSums, xtz: FloatArray, zs: FloatArray, ztz: float, n_obs: int, reml: bool
) -> float:
    """Derivative of the profiled objective with respect to ``log gamma`` (closed form).

    With ``d_i = gamma / (1 + n_i gamma)``: ``d log|V| / d gamma = sum n_i / (1 + n_i gamma)``,
    ``d log|A| / d gamma = -sum d_i' s_i' A^-1 s_i`` and, by the envelope theorem,
    ``d (r' V^-1 r) / d gamma = -sum d_i' (sum_j r_ij)^2`` with ``d_i' = 1 / (1 + n_i gamma)^2``.
    """
    ratio = np.exp(log_ratio)
    d = ratio / (1.0 + sums.n * ratio)
    dd = 1.0 / (1.0 + sums.n * ratio) ** 2
    a = sums.xtx - (sums.xs * d[:, None]).T @ sums.xs
    c = xtz - sums.xs.T @ (d * zs)
    beta = np.linalg.solve(a, c)
    quad = ztz - float(np.sum(d * zs * zs)) - float(c @ beta)
    if not quad > 0.0:  # a response the fixed effects explain exactly: no residual variance to split
        raise FitError("the linear mixed model has no residual variance (the response is fitted exactly)")
    resid_sums = zs - sums.xs @ beta
    dof = n_obs - a.shape[0] if reml else n_obs
    slope = dof * (-float(np.sum(dd * resid_sums**2))) / quad + float(np.sum(sums.n / (1.0 + sums.n * ratio)))
    if reml:
        a_inv_s = np.linalg.solve(a, sums.xs.T)
        slope -= float(np.sum(dd * np.einsum("ij,ji->i", sums.xs, a_inv_s)))
    return float(slope * ratio)


def _minimise(
    objective: Callable[[float], float], slope: Callable[[float], float], start: float | None
) -> float:
    """Minimiser of the profiled objective in log gamma, to near machine precision.

    A coarse bounded search (or the previous PQL iteration's value) gives a point near the optimum;
    Brent's root finder on the closed-form slope then polishes it.
    """
    lo, hi = _LOG_RATIO_BOUNDS
    if start is None or not lo + 1.0 < start < hi - 1.0:
        res = optimize.minimize_scalar(objective, bounds=(lo, hi), method="bounded", options={"xatol": 1e-4})
        start = float(res.x)
    if slope(lo) >= 0.0:
        return lo  # the likelihood increases towards zero participant variance: boundary estimate
    step = 1e-4
    while True:
        left, right = max(lo, start - step), min(hi, start + step)
        if slope(left) <= 0.0 <= slope(right):
            return float(optimize.brentq(slope, left, right, xtol=1e-14, rtol=4 * np.finfo(float).eps))
        if left <= lo and right >= hi:
            raise FitError("could not bracket the variance ratio of the linear mixed model step")
        step *= 8.0


def fit_random_intercept_lmm(
    z: FloatArray,
    x: FloatArray,
    group: IntArray,
    sums: GroupSums,
    *,
    method: LmmMethod = "REML",
    log_ratio_start: float | None = None,
) -> LmmFit:
    """Fit ``z = X beta + b[group] + e`` by REML or ML.

    Parameters
    ----------
    z:
        Response, shape (n,).
    x:
        Full-rank fixed-effects matrix, shape (n, p).
    group:
        Participant index per row, 0..m-1.
    sums:
        :class:`GroupSums` of ``x`` and ``group``.
    method:
        ``"REML"`` (restricted likelihood, as SPSS and nlme's default) or ``"ML"``.
    log_ratio_start:
        Optional starting value of ``log(sigma_b^2 / sigma^2)`` (previous PQL iteration).

    Returns
    -------
    LmmFit
    """
    if method not in ("REML", "ML"):
        raise FitError(f"method must be 'REML' or 'ML', got {method!r}")
    reml = method == "REML"
    n_obs = z.size
    zs = np.asarray(np.bincount(group, weights=z, minlength=sums.n.size), dtype=float)
    xtz = x.T @ z
    ztz = float(z @ z)

    def objective(t: float) -> float:
        return _profile(t, sums, xtz, zs, ztz, n_obs, reml)[0]

    def slope(t: float) -> float:
        return _profile_slope(t, sums, xtz, zs, ztz, n_obs, reml)

    t_hat = _minimise(objective, slope, log_ratio_start)
    at_boundary = t_hat <= _LOG_RATIO_BOUNDS[0] + 1e-6
    obj, beta, a, sigma2, _ = _profile(t_hat, sums, xtz, zs, ztz, n_obs, reml)
    if not np.isfinite(obj) or sigma2 <= 0.0:
        raise FitError("the linear mixed model step failed (non-finite likelihood)")
    ratio = 0.0 if at_boundary else float(np.exp(t_hat))
    d = ratio / (1.0 + sums.n * ratio)
    blup = d * (zs - sums.xs @ beta)
    p = x.shape[1]
    dof = n_obs - p if reml else n_obs
    loglik = -0.5 * (obj + dof * (1.0 + np.log(2.0 * np.pi)))
    return LmmFit(
        beta=beta,
        vcov=np.asarray(sigma2 * np.linalg.inv(a), dtype=float),
        sigma2=float(sigma2),
        participant_var=float(ratio * sigma2),
        random_effects=blup,
        loglik=float(loglik),
        at_boundary=bool(at_boundary),
    )
