"""Pairwise comparisons of estimated marginal means, Holm-adjusted (the paper's sequential Bonferroni).

A comparison ``A - B`` is the difference of response-scale means ``exp(eta_A) - exp(eta_B)`` with the
delta-method standard error ``sqrt(g V g')``, ``g = exp(eta_A) L_A - exp(eta_B) L_B``, tested by t with
the residual degrees of freedom (SPSS GENLINMIXED's default: pairwise contrasts of estimated means on
the original scale) or by z. The percent change relative to the second mean, ``100 (mu_A / mu_B - 1)``,
comes with its own delta-method SE ``100 (mu_A / mu_B) SE(eta_A - eta_B)``; its p-value is that of the
difference. Holm 1979 (Scand J Stat 6:65): sort the m raw p-values, multiply the k-th smallest by
``m - k + 1``, take running maxima, cap at one.
"""

from __future__ import annotations

from itertools import combinations
from typing import Literal

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy import stats

from bowden.errors import ParameterError
from bowden.stats.glmm import GlmmResult
from bowden.stats.tests_of_effects import DfMethod, degrees_of_freedom, reference_rows

Family = Literal["whole_table", "by_group"]


def holm_adjust(p_values: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Holm's step-down adjusted p-values (same order as the input).

    Examples
    --------
    >>> holm_adjust([0.01, 0.04, 0.03]).round(3).tolist()
    [0.03, 0.06, 0.06]
    """
    p = np.asarray(p_values, dtype=float)
    if p.ndim != 1:
        raise ParameterError("p_values must be one-dimensional")
    if p.size and (np.any(~np.isfinite(p)) or np.any(p < 0.0) or np.any(p > 1.0)):
        raise ParameterError("p_values must lie in [0, 1]")
    m = p.size
    order = np.argsort(p, kind="stable")
    scaled = p[order] * (m - np.arange(m))
    adjusted = np.minimum(1.0, np.maximum.accumulate(scaled))
    out = np.empty(m)
    out[order] = adjusted
    return out


def pairwise_comparisons(
    result: GlmmResult,
    factor: Literal["condition", "speed"] = "condition",
    *,
    by: Literal["condition", "speed"] | None = None,
    family: Family = "by_group",
    reverse: bool = False,
    df_method: DfMethod = "residual",
) -> pd.DataFrame:
    """All pairwise differences of the marginal means of ``factor``, Holm-adjusted.

    Parameters
    ----------
    result:
        A fitted GLMM.
    factor:
        Factor whose levels are compared (pooled over the other factor unless ``by`` is given).
    by:
        Compare within each level of this (other) factor, e.g. conditions per speed.
    family:
        With ``by``: ``"by_group"`` adjusts within each level of ``by`` (emmeans' default), ``"whole_table"``
        adjusts all comparisons of the table together. Without ``by`` the table is one family.
    reverse:
        False: ``earlier - later`` in level order (emmeans ``pairs``), e.g. ``no_suit - pretension``.
        True: ``later - earlier`` (the paper's ``pre - no``); pairs keep the same order.
    df_method:
        ``"residual"`` (t with n - p df, SPSS) or ``"asymptotic"`` (z).

    Returns
    -------
    pandas.DataFrame
        One row per comparison: [``by``,] ``contrast``, ``level_a``, ``level_b``, ``mean_a``, ``mean_b``,
        ``estimate`` (mean_a - mean_b), ``se``, ``df``, ``statistic``, ``p_raw``, ``p_holm``, ``ratio``,
        ``percent_change``, ``percent_change_se``.
    """
    if factor not in ("condition", "speed"):
        raise ParameterError(f"factor must be 'condition' or 'speed', got {factor!r}")
    if by is not None and by not in ("condition", "speed"):
        raise ParameterError(f"by must be 'condition', 'speed' or None, got {by!r}")
    if by == factor:
        raise ParameterError("by must be the other factor than factor")
    if family not in ("whole_table", "by_group"):
        raise ParameterError(f"family must be 'whole_table' or 'by_group', got {family!r}")
    df = degrees_of_freedom(result, df_method)
    beta = result.coef.to_numpy()
    cov = result.vcov.to_numpy()
    if by is None:
        levels, rows = reference_rows(result, factor)
        groups: list[tuple[str | None, pd.Series, np.ndarray]] = [(None, levels[factor], rows)]
    else:
        levels, rows = reference_rows(result, "cell")
        groups = []
        for group_level in dict.fromkeys(levels[by]):
            mask = (levels[by] == group_level).to_numpy()
            groups.append((str(group_level), levels.loc[mask, factor].reset_index(drop=True), rows[mask]))
    records = []
    for group_level, names, grid in groups:
        mu = np.exp(grid @ beta)
        for i, j in combinations(range(len(names)), 2):
            a, b = (j, i) if reverse else (i, j)
            record = _comparison(names, grid, mu, cov, df, a, b)
            records.append(record if by is None else {by: group_level, **record})
    table = pd.DataFrame(records)
    if by is not None and family == "by_group":
        table["p_holm"] = np.concatenate(
            [holm_adjust(table.loc[table[by] == g, "p_raw"].to_numpy()) for g, _, _ in groups]
        )
    else:
        table["p_holm"] = holm_adjust(table["p_raw"].to_numpy())
    columns = [
        c for c in table.columns if c not in ("ratio", "percent_change", "percent_change_se", "p_holm")
    ]
    columns += ["p_holm", "ratio", "percent_change", "percent_change_se"]
    return table[columns]


def _comparison(names: pd.Series, grid: np.ndarray, mu: np.ndarray, cov: np.ndarray, df: float,
                a: int, b: int) -> dict[str, object]:
    """Level ``a`` against level ``b`` of one family: the difference of the marginal means with its
    delta-method standard error, its t (or z) test, and the ratio with its percent change."""
    grad = mu[a] * grid[a] - mu[b] * grid[b]
    se = float(np.sqrt(grad @ cov @ grad))
    diff_l = grid[a] - grid[b]
    log_se = float(np.sqrt(diff_l @ cov @ diff_l))
    estimate = float(mu[a] - mu[b])
    statistic = estimate / se
    p_raw = float(
        2.0 * (stats.t.sf(abs(statistic), df) if np.isfinite(df) else stats.norm.sf(abs(statistic)))
    )
    ratio = float(mu[a] / mu[b])
    return {
        "contrast": f"{names[a]} - {names[b]}",
        "level_a": str(names[a]),
        "level_b": str(names[b]),
        "mean_a": float(mu[a]),
        "mean_b": float(mu[b]),
        "estimate": estimate,
        "se": se,
        "df": df,
        "statistic": statistic,
        "p_raw": p_raw,
        "ratio": ratio,
        "percent_change": 100.0 * (ratio - 1.0),
        "percent_change_se": 100.0 * ratio * log_se,
    }
