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

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import pandas as pd

from bowden.errors import FitError, ParameterError
from bowden.stats.design import Design, FloatArray, build_design
from bowden.stats.lmm import GroupSums, LmmFit, fit_random_intercept_lmm

GlmmMethod = Literal["pql-reml", "pql-ml", "laplace", "agq"]
METHODS: tuple[str, ...] = ("pql-reml", "pql-ml", "laplace", "agq")


@dataclass(frozen=True, kw_only=True)
class GlmmOptions:
    """How to fit the gamma GLMM.

    Attributes
    ----------
    method:
        ``"pql-reml"`` (SPSS-like, default), ``"pql-ml"``, ``"laplace"`` or ``"agq"``.
    n_agq:
        Quadrature nodes per participant for ``"agq"`` (1 is the Laplace approximation).
    tolerance:
        PQL: stop when the largest change of the linear predictor is below this. ML: gradient norm
        target of the outer optimiser.
    max_iterations:
        PQL iterations or ML Newton/BFGS iterations before giving up with :class:`FitError`.
    """

    method: GlmmMethod = "pql-reml"
    n_agq: int = 15
    tolerance: float = 1e-10
    max_iterations: int = 200

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ParameterError(f"method must be one of {METHODS}, got {self.method!r}")
        if not 1 <= self.n_agq <= 101:
            raise ParameterError("n_agq must be in 1..101")
        if not 0.0 < self.tolerance < 1e-2:
            raise ParameterError("tolerance must be in (0, 0.01)")
        if self.max_iterations < 1:
            raise ParameterError("max_iterations must be >= 1")


@dataclass(frozen=True, kw_only=True)
class GlmmResult:
    """A fitted gamma GLMM.

    Attributes
    ----------
    method:
        Fitting method (see :class:`GlmmOptions`).
    coef, se:
        Fixed-effect coefficients on the log scale (sum-to-zero coding, R's column order) and their
        standard errors.
    vcov:
        Covariance matrix of ``coef``.
    participant_var:
        Variance of the random intercept (log scale).
    dispersion:
        Gamma dispersion ``phi = 1 / shape`` (``Var(y | b) = phi mu^2``).
    random_effects:
        Predicted random intercepts per participant (PQL: BLUPs of the pseudo-model; ML: conditional modes).
    residual_df:
        ``n_obs - p``, the denominator degrees of freedom of SPSS's default tests.
    loglik:
        ML: marginal log-likelihood (Laplace or quadrature). PQL: (restricted) log-likelihood of the
        final pseudo-model, not comparable across data sets.
    converged, iterations, final_change:
        Diagnostics: PQL iterations and the last change of the linear predictor; ML iterations and the
        final gradient norm.
    design:
        The design the model was fitted on (levels, coding, reference grid).
    """

    method: str
    coef: pd.Series
    se: pd.Series
    vcov: pd.DataFrame
    participant_var: float
    dispersion: float
    random_effects: pd.Series
    residual_df: int
    loglik: float
    converged: bool
    iterations: int
    final_change: float
    design: Design = field(repr=False)

    @property
    def n_obs(self) -> int:
        return self.design.n_obs

    @property
    def n_participants(self) -> int:
        return self.design.n_participants

    def summary(self) -> pd.DataFrame:
        """Coefficient table: estimate, SE, z/t statistic (log scale)."""
        return pd.DataFrame({"estimate": self.coef, "se": self.se, "statistic": self.coef / self.se})


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
    pql = _fit_pql(design, options, "REML" if options.method == "pql-reml" else "ML")
    if options.method in ("pql-reml", "pql-ml"):
        return pql
    # Imported here: the ML code needs the PQL answer as its starting point.
    from bowden.stats.marginal import fit_marginal_ml

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
    return _result(
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


def _result(
    design: Design,
    method: str,
    beta: FloatArray,
    vcov: FloatArray,
    participant_var: float,
    dispersion: float,
    random_effects: FloatArray,
    loglik: float,
    iterations: int,
    final_change: float,
) -> GlmmResult:
    names = list(design.coef_names)
    return GlmmResult(
        method=method,
        coef=pd.Series(beta, index=names, name="coef"),
        se=pd.Series(np.sqrt(np.diag(vcov)), index=names, name="se"),
        vcov=pd.DataFrame(vcov, index=names, columns=names),
        participant_var=float(participant_var),
        dispersion=float(dispersion),
        random_effects=pd.Series(random_effects, index=list(design.participants), name="random_effect"),
        residual_df=design.n_obs - len(names),
        loglik=float(loglik),
        converged=True,
        iterations=int(iterations),
        final_change=float(final_change),
        design=design,
    )
