"""The gamma GLMM's options and result, shared by the PQL fit (:mod:`bowden.stats.glmm`) and the
marginal-likelihood fit (:mod:`bowden.stats.marginal`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import pandas as pd

from bowden.errors import ParameterError
from bowden.stats.design import Design, FloatArray

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


def glmm_result(
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
