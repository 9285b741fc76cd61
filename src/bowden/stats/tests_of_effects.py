"""Type-III Wald tests of the fixed effects and estimated marginal means on the response scale.

Type III: with sum-to-zero coding the hypothesis "no main effect of condition" (equal unweighted
marginal means over speeds) is ``beta_condition = 0``; its Wald statistic is
``W = b' V^-1 b`` over that term's coefficients, ``F = W / q`` with ``q`` the term's columns. SPSS
GENLINMIXED refers F to ``F(q, n - p)`` ("residual" degrees of freedom, its default); ``"asymptotic"``
refers ``W`` to chi-square(q) as ``car::Anova`` does.

Marginal means follow SPSS and emmeans: the linear predictor is averaged with equal weights over the
other factor's levels on the link scale, then back-transformed, ``mean = exp(L beta)``, with the
delta-method standard error ``mean * sqrt(L V L')`` (Searle, Speed & Milliken 1980, Am Stat 34:216).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import pandas as pd
from scipy import stats

from bowden.errors import ParameterError
from bowden.stats.design import FloatArray, model_row
from bowden.stats.glmm import GlmmResult

DfMethod = Literal["residual", "asymptotic"]
Factor = Literal["condition", "speed", "cell"]


def _check_df_method(df_method: str) -> None:
    if df_method not in ("residual", "asymptotic"):
        raise ParameterError(f"df_method must be 'residual' or 'asymptotic', got {df_method!r}")


def type_iii_tests(result: GlmmResult, *, df_method: DfMethod = "residual") -> pd.DataFrame:
    """Type-III Wald tests of condition, speed and their interaction.

    Parameters
    ----------
    result:
        A fitted :class:`~bowden.stats.GlmmResult`.
    df_method:
        ``"residual"``: F test with ``(q, n - p)`` degrees of freedom (SPSS default).
        ``"asymptotic"``: chi-square test of ``W`` with ``q`` degrees of freedom.

    Returns
    -------
    pandas.DataFrame
        Index ``condition, speed, condition:speed``; columns ``chisq`` (Wald W), ``df1``, ``df2``
        (``inf`` for asymptotic), ``F`` (= W / df1) and ``p``.
    """
    _check_df_method(df_method)
    beta = result.coef.to_numpy()
    cov = result.vcov.to_numpy()
    rows = []
    for term, cols in result.design.term_columns.items():
        b = beta[cols]
        wald = float(b @ np.linalg.solve(cov[np.ix_(cols, cols)], b))
        q = int(cols.size)
        if df_method == "residual":
            df2 = float(result.residual_df)
            p = float(stats.f.sf(wald / q, q, df2))
        else:
            df2 = np.inf
            p = float(stats.chi2.sf(wald, q))
        rows.append({"term": term, "chisq": wald, "df1": q, "df2": df2, "F": wald / q, "p": p})
    return pd.DataFrame(rows).set_index("term")


def reference_rows(result: GlmmResult, factor: Factor) -> tuple[pd.DataFrame, FloatArray]:
    """Levels and contrast rows ``L`` (one per level) of the marginal means of ``factor``.

    Means of a main effect average the cell rows over the other factor with equal weights.
    """
    design = result.design
    n_c, n_v = len(design.conditions), len(design.speeds)
    grid = np.array([[model_row(c, v, n_c, n_v) for v in range(n_v)] for c in range(n_c)])
    if factor == "condition":
        return pd.DataFrame({"condition": design.conditions}), grid.mean(axis=1)
    if factor == "speed":
        return pd.DataFrame({"speed": design.speeds}), grid.mean(axis=0)
    if factor == "cell":
        levels = pd.DataFrame(
            [(c, v) for v in design.speeds for c in design.conditions], columns=["condition", "speed"]
        )
        # Conditions vary fastest within speed, as emmeans' "condition | speed" grid.
        return levels, grid.transpose(1, 0, 2).reshape(n_c * n_v, -1)
    raise ParameterError(f"factor must be 'condition', 'speed' or 'cell', got {factor!r}")


def degrees_of_freedom(result: GlmmResult, df_method: DfMethod) -> float:
    """Denominator degrees of freedom for t tests and intervals (``inf``: normal)."""
    _check_df_method(df_method)
    return float(result.residual_df) if df_method == "residual" else float("inf")


def estimated_marginal_means(
    result: GlmmResult,
    factor: Factor = "condition",
    *,
    df_method: DfMethod = "residual",
    confidence: float = 0.95,
) -> pd.DataFrame:
    """Estimated marginal means on the response scale.

    Parameters
    ----------
    result:
        A fitted GLMM.
    factor:
        ``"condition"`` (averaged over speeds), ``"speed"`` (averaged over conditions) or ``"cell"``.
    df_method:
        Degrees of freedom of the interval (see :func:`type_iii_tests`).
    confidence:
        Level of the interval, computed on the log scale and back-transformed (always positive).

    Returns
    -------
    pandas.DataFrame
        Level column(s), ``mean``, ``se`` (delta method), ``log_mean``, ``log_se``, ``df``,
        ``ci_low``, ``ci_high``.
    """
    if not 0.0 < confidence < 1.0:
        raise ParameterError("confidence must be in (0, 1)")
    levels, rows = reference_rows(result, factor)
    beta = result.coef.to_numpy()
    cov = result.vcov.to_numpy()
    log_mean = rows @ beta
    log_se = np.sqrt(np.einsum("ij,jk,ik->i", rows, cov, rows))
    df = degrees_of_freedom(result, df_method)
    crit = (
        float(stats.t.ppf(0.5 + confidence / 2.0, df))
        if np.isfinite(df)
        else float(stats.norm.ppf(0.5 + confidence / 2.0))
    )
    out = levels.copy()
    out["mean"] = np.exp(log_mean)
    out["se"] = np.exp(log_mean) * log_se
    out["log_mean"] = log_mean
    out["log_se"] = log_se
    out["df"] = df
    out["ci_low"] = np.exp(log_mean - crit * log_se)
    out["ci_high"] = np.exp(log_mean + crit * log_se)
    return out
