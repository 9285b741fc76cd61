"""Gamma GLMM with log link and a random intercept per participant (the paper's SPSS model).

``log E[y | b] = X beta + b_participant``, ``b ~ N(0, sigma_b^2)``, ``Var(y | b) = phi E[y | b]^2``.

Methods
-------
``"pql-reml"`` (default)
    Linearised pseudo-likelihood as SPSS GENLINMIXED and SAS GLIMMIX (RSPL; Wolfinger & O'Connell 1993,
    J Stat Comput Simul 48:233; Breslow & Clayton 1993, J Am Stat Assoc 88:9): working response
    ``z = eta + (y - mu) / mu`` with working weight ``1 / (V(mu) g'(mu)^2) = 1`` for gamma/log, a linear
    mixed model fitted by REML on ``z``, repeated until the linear predictor stops changing. The
    residual variance of the pseudo-model is the dispersion ``phi``; the coefficient covariance is the
    model-based ``phi (X' V^-1 X)^-1`` of the last step.
``"pql-ml"``
    The same loop with ML at each step (what ``MASS::glmmPQL`` does, with a looser stopping rule).
``"laplace"`` / ``"agq"``
    Maximum likelihood of the marginal likelihood by the Laplace approximation (as glmmTMB) or by
    adaptive Gauss-Hermite quadrature with ``n_agq`` nodes (see :mod:`bowden.stats.marginal`).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import pandas as pd

from bowden.errors import FitError
from bowden.stats.design import Design, FloatArray, build_design
from bowden.stats.glmm_result import METHODS, GlmmMethod, GlmmOptions, GlmmResult, glmm_result
from bowden.stats.lmm import GroupSums, LmmFit, fit_random_intercept_lmm
from bowden.stats.marginal import fit_marginal_ml

__all__ = ["METHODS", "GlmmMethod", "GlmmOptions", "GlmmResult", "fit_design", "fit_gamma_glmm"]

def fit_gamma_glmm(
    data: pd.DataFrame,
    *,
    options: GlmmOptions | None = None,
    participant: str = "participant",
    condition: str = "condition",
    speed: str = "speed",
    value: str = "value",
) -> GlmmResult:
    """Fit ``value ~ condition * speed + (1 | participant)``, gamma family, log link.

    Parameters
    ----------
    data:
        Tidy table, one row per observation; ``value`` must be > 0.
    options:
        :class:`GlmmOptions` (default: SPSS-like PQL with REML).
    participant, condition, speed, value:
        Column names.

    Returns
    -------
    GlmmResult

    Raises
    ------
    bowden.errors.OutcomeTableError
        Missing columns, values <= 0 or not finite, empty condition x speed cells.
    bowden.errors.FitError
        The fit did not converge within ``options.max_iterations``.

    Examples
    --------
    >>> from bowden.stats import fit_gamma_glmm, simulate_gamma_glmm
    >>> fit = fit_gamma_glmm(simulate_gamma_glmm(seed=1))
    >>> fit.converged, fit.residual_df
    (True, 1824)
    """
    options = options or GlmmOptions()
    design = build_design(data, participant=participant, condition=condition, speed=speed, value=value)
    return fit_design(design, options)


def fit_design(design: Design, options: GlmmOptions) -> GlmmResult:
    """Fit a prepared :class:`Design` (see :func:`fit_gamma_glmm`)."""
    if design.y.size and float(np.ptp(design.y)) == 0.0:
        raise FitError(
            f"every value is {float(design.y[0]):g}: a constant outcome has no condition or speed effect "
            "to model (the dispersion is zero)"
        )
    pql = _fit_pql(design, options, "REML" if options.method == "pql-reml" else "ML")
    if options.method in ("pql-reml", "pql-ml"):
        return pql
    # Imported here: the ML code needs the PQL answer as its starting point.

    n_nodes = 1 if options.method == "laplace" else options.n_agq
    return fit_marginal_ml(design, pql, n_nodes=n_nodes, options=options)


def _glm_start(design: Design) -> FloatArray:
    """Linear predictor of the gamma/log GLM without random effects (IRLS: OLS on z, unit weights)."""
    x, y = design.x, design.y
    eta = np.full(y.size, np.log(np.mean(y)))
    for _ in range(50):
        z = eta + (y - np.exp(eta)) / np.exp(eta)
        beta, *_ = np.linalg.lstsq(x, z, rcond=None)
        new = x @ beta
        done = float(np.max(np.abs(new - eta))) < 1e-12
        eta = new
        if done:
            break
    return eta


def _fit_pql(design: Design, options: GlmmOptions, lmm_method: Literal["REML", "ML"]) -> GlmmResult:
    x, y, group = design.x, design.y, design.group
    sums = GroupSums.of(x, group, design.n_participants)
    eta = _glm_start(design)
    log_ratio: float | None = None
    fit: LmmFit | None = None
    change = np.inf
    iteration = 0
    for iteration in range(1, options.max_iterations + 1):  # noqa: B007 - reported after the loop
        mu = np.exp(eta)
        z = eta + (y - mu) / mu
        fit = fit_random_intercept_lmm(z, x, group, sums, method=lmm_method, log_ratio_start=log_ratio)
        new_eta = x @ fit.beta + fit.random_effects[group]
        change = float(np.max(np.abs(new_eta - eta)))
        eta = new_eta
        if fit.participant_var > 0.0:
            log_ratio = float(np.log(fit.participant_var / fit.sigma2))
        if change < options.tolerance:
            break
    assert fit is not None
    if not change < options.tolerance:
        raise FitError(
            f"PQL did not converge in {options.max_iterations} iterations "
            f"(last change of the linear predictor {change:.3g}); raise max_iterations or check the data"
        )
    return glmm_result(
        design,
        options.method if options.method.startswith("pql") else "pql-" + lmm_method.lower(),
        fit.beta,
        fit.vcov,
        fit.participant_var,
        fit.sigma2,
        fit.random_effects,
        fit.loglik,
        iteration,
        change,
    )
