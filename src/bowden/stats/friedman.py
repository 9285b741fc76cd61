"""Friedman's test and its post-hoc comparisons of mean ranks, equivalent to MATLAB's
``friedman(X, reps)`` followed by ``multcompare(stats, 'CType', 'bonferroni')``.

Within each block (participant; ``reps`` consecutive rows) all ``reps x c`` values are ranked together
with midranks for ties. With ``n`` blocks and mean ranks ``R_j`` per column,

``sigma^2 = c r (r c + 1) / 12 - sum(t^3 - t) / (12 n (r c - 1))``  (tie-corrected rank variance,
the sum over every tie group of every block), ``chi2 = n r sum_j (R_j - mean R)^2 / sigma^2`` with
``c - 1`` degrees of freedom (Friedman 1937, J Am Stat Assoc 32:675; Hollander & Wolfe, Nonparametric
Statistical Methods, 1999, ch. 7). The post-hoc compares mean ranks by ``z = (R_i - R_j) /
sqrt(2 sigma^2 / n)``; Bonferroni: ``p = min(1, K 2 Phi(-|z|))``, ``K = c (c - 1) / 2``, and intervals
``+- Phi^-1(1 - alpha / (2K)) sqrt(2 sigma^2 / n)``. Unlike scikit-posthocs' ``posthoc_siegel_friedman``
the rank variance keeps the tie correction, which Likert and Borg scores always need.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations
from typing import Literal

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy import stats

from bowden.contracts import CONDITIONS
from bowden.errors import OutcomeTableError, ParameterError
from bowden.stats.design import order_levels
from bowden.stats.pairwise import holm_adjust


@dataclass(frozen=True, kw_only=True)
class FriedmanResult:
    """Friedman's test (MATLAB ``friedman``'s table and ``stats`` structure).

    Attributes
    ----------
    statistic:
        Chi-square statistic.
    df:
        ``c - 1``.
    p:
        Upper tail of chi-square(df).
    sigma:
        Square root of the tie-corrected rank variance (MATLAB ``stats.sigma``).
    mean_ranks:
        Mean rank per column (MATLAB ``stats.meanranks``), indexed by column label.
    n_blocks, reps:
        Blocks (MATLAB ``stats.n``) and rows per block.
    """

    statistic: float
    df: int
    p: float
    sigma: float
    mean_ranks: pd.Series
    n_blocks: int
    reps: int


def friedman(x: npt.ArrayLike, reps: int = 1, *, labels: Sequence[str] | None = None) -> FriedmanResult:
    """Friedman's test on a matrix, like MATLAB ``friedman(x, reps)``.

    Parameters
    ----------
    x:
        Shape ``(n * reps, c)``: columns are conditions, each block is ``reps`` consecutive rows.
    reps:
        Rows per block.
    labels:
        Column labels (default ``"1".."c"``).

    Examples
    --------
    MATLAB's documented example (popcorn yield, 3 brands, 2 popper types x 3 batches):

    >>> popcorn = [[5.5, 4.5, 3.5], [5.5, 4.5, 4.0], [6.0, 4.0, 3.0],
    ...            [6.5, 5.0, 4.0], [7.0, 5.5, 5.0], [7.0, 5.0, 4.5]]
    >>> res = friedman(popcorn, 3)
    >>> round(res.statistic, 10), round(res.p, 10)
    (13.7586206897, 0.0010288534)
    """
    arr = np.asarray(x, dtype=float)
    if arr.ndim != 2 or arr.shape[1] < 2:
        raise OutcomeTableError(f"x must be a matrix with at least two columns, got shape {arr.shape}")
    if not isinstance(reps, int | np.integer) or reps < 1:
        raise ParameterError("reps must be a positive integer")
    rows, c = arr.shape
    if rows % reps or rows == 0:
        raise OutcomeTableError(f"{rows} rows do not split into blocks of reps={reps}")
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        raise OutcomeTableError(
            f"x holds a missing or non-finite value at row {bad[0][0]}, column {bad[0][1]}"
        )
    n = rows // reps
    if n < 2:
        raise OutcomeTableError("Friedman's test needs at least two blocks")
    names = [str(v) for v in labels] if labels is not None else [str(k + 1) for k in range(c)]
    if len(names) != c:
        raise ParameterError(f"labels needs {c} names")
    blocks = arr.reshape(n, reps * c)
    ranks = stats.rankdata(blocks, axis=1).reshape(rows, c)
    ties = 0.0
    for block in blocks:
        _, counts = np.unique(block, return_counts=True)
        ties += float(np.sum(counts.astype(float) ** 3 - counts))
    sigma2 = c * reps * (reps * c + 1) / 12.0 - ties / (12.0 * n * (reps * c - 1))
    mean_ranks = ranks.mean(axis=0)
    ss_columns = n * reps * float(np.sum((mean_ranks - mean_ranks.mean()) ** 2))
    if sigma2 <= 0.0:
        # Every value of every block tied: no information about the columns.
        statistic, p = 0.0, 1.0
    else:
        statistic = ss_columns / sigma2
        p = float(stats.chi2.sf(statistic, c - 1))
    return FriedmanResult(
        statistic=float(statistic),
        df=c - 1,
        p=p,
        sigma=float(np.sqrt(max(sigma2, 0.0))),
        mean_ranks=pd.Series(mean_ranks, index=names, name="mean_rank"),
        n_blocks=n,
        reps=int(reps),
    )


def friedman_multcompare(
    result: FriedmanResult,
    *,
    alpha: float = 0.05,
    correction: Literal["bonferroni", "holm", "none"] = "bonferroni",
) -> pd.DataFrame:
    """Pairwise comparisons of mean ranks, like MATLAB ``multcompare(stats, 'CType', 'bonferroni')``.

    Parameters
    ----------
    result:
        Output of :func:`friedman` or :func:`friedman_test`.
    alpha:
        Family-wise level of the simultaneous intervals.
    correction:
        ``"bonferroni"`` (MATLAB, the paper), ``"holm"`` or ``"none"`` for the p-values. The intervals
        are Bonferroni intervals for ``"bonferroni"`` and ``"holm"`` and unadjusted for ``"none"``.

    Returns
    -------
    pandas.DataFrame
        ``group_a, group_b, lower, difference, upper, p`` in MATLAB's row order (1-2, 1-3, ..., 2-3, ...),
        ``difference`` = mean rank of a minus mean rank of b.

    Examples
    --------
    >>> popcorn = [[5.5, 4.5, 3.5], [5.5, 4.5, 4.0], [6.0, 4.0, 3.0],
    ...            [6.5, 5.0, 4.0], [7.0, 5.5, 5.0], [7.0, 5.0, 4.5]]
    >>> friedman_multcompare(friedman(popcorn, 3))["p"].round(6).tolist()
    [0.682274, 0.098161, 1.0]
    """
    if not 0.0 < alpha < 1.0:
        raise ParameterError("alpha must be in (0, 1)")
    if correction not in ("bonferroni", "holm", "none"):
        raise ParameterError(f"correction must be 'bonferroni', 'holm' or 'none', got {correction!r}")
    ranks = result.mean_ranks
    pairs = list(combinations(range(ranks.size), 2))
    k = len(pairs)
    se = result.sigma * np.sqrt(2.0 / result.n_blocks)
    diff = np.array([ranks.iloc[i] - ranks.iloc[j] for i, j in pairs])
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(se > 0.0, diff / se, 0.0)
    raw = 2.0 * stats.norm.sf(np.abs(z))
    if correction == "bonferroni":
        p = np.minimum(1.0, k * raw)
    elif correction == "holm":
        p = holm_adjust(raw)
    else:
        p = raw
    level = alpha / (2.0 * k) if correction != "none" else alpha / 2.0
    half = float(stats.norm.isf(level)) * se
    return pd.DataFrame(
        {
            "group_a": [ranks.index[i] for i, _ in pairs],
            "group_b": [ranks.index[j] for _, j in pairs],
            "lower": diff - half,
            "difference": diff,
            "upper": diff + half,
            "p": p,
        }
    )


def friedman_test(
    data: pd.DataFrame,
    *,
    participant: str = "participant",
    condition: str = "condition",
    value: str = "value",
) -> FriedmanResult:
    """Friedman's test on a tidy table (questionnaire scores per participant and condition).

    Each participant is a block; every participant needs the same number of rows in every condition
    (that number is ``reps``). Conditions are ordered as :data:`bowden.contracts.CONDITIONS` when they
    match, otherwise as first seen (or a categorical's order).

    Raises
    ------
    OutcomeTableError
        Missing column, non-numeric or missing score, or an incomplete participant.
    """
    for col in (participant, condition, value):
        if col not in data.columns:
            raise OutcomeTableError(f"column {col!r} is missing (columns: {list(data.columns)})")
    scores = pd.to_numeric(data[value], errors="coerce")
    missing = scores.isna().to_numpy()
    if missing.any():
        row = data.index[int(np.argmax(missing))]
        raise OutcomeTableError(f"column {value!r} has no numeric score in row {row!r}")
    levels = order_levels(data[condition], CONDITIONS)
    frame = pd.DataFrame(
        {
            "p": data[participant].astype(str).to_numpy(),
            "c": data[condition].astype(str).to_numpy(),
            "v": scores.to_numpy(dtype=float),
        }
    )
    counts = frame.groupby(["p", "c"], sort=False).size().unstack("c").reindex(columns=list(levels))
    table = counts.to_numpy(dtype=float)
    if np.isnan(table).any() or np.unique(table).size != 1:
        # The count most cells have is the design; the culprits are the participants who differ from it
        # (comparing with the first participant would name everyone when the first is the culprit).
        finite = table[np.isfinite(table)]
        values, frequency = np.unique(finite, return_counts=True)
        expected = values[np.argmax(frequency)] if finite.size else 1.0
        uneven = counts.index[(np.isnan(table) | (table != expected)).any(axis=1)].tolist()
        raise OutcomeTableError(
            f"every participant needs the same number of scores in every {condition!r} "
            f"({int(expected)} here); check participant(s) {uneven}"
        )
    reps = int(table[0, 0])
    frame["k"] = frame.groupby(["p", "c"], sort=False).cumcount()
    wide = frame.pivot(index=["p", "k"], columns="c", values="v")
    wide = wide.reindex(columns=list(levels))
    order = list(dict.fromkeys(frame["p"]))
    wide = wide.reindex(pd.MultiIndex.from_product([order, range(reps)], names=["p", "k"]))
    return friedman(wide.to_numpy(), reps, labels=list(levels))
