"""Summaries of a sweep's rows: per-configuration means, ranks, the Pareto front, paired differences.

The two scores of the paper's open question are the **tension RMSE** over the entire cycle and the
**lowering-onset spike**, the peak percent error of the lowering phase (paper, Discussion; supplement
Table S3). Each configuration's score is the mean over its rows (seeds × participants × conditions ×
speeds, each row already the mean over repetitions). The spike's size is the mean of |peak| per
repetition (``peak_percent_error_abs_pct``): once the blend removes the positive onset spike, the
largest lowering error can turn negative, and a mean of signed peaks would then reward a blend for
errors that cancel.

A configuration is on the Pareto front when no other is at least as good on both scores and better
on one. Because every configuration of a seed runs the same participants with the same noise
(common random numbers), two configurations are compared by paired per-participant differences
(:func:`paired_difference`), with a t-interval over participants.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from rich.table import Table
from scipy import stats

from bowden.analysis.outcomes import (
    ELEVATION_RMSE,
    PEAK_PERCENT_ERROR,
    PEAK_PERCENT_ERROR_TIME,
    TENSION_RMSE,
)
from bowden.errors import ParameterError
from bowden.sweep import axes as ax
from bowden.sweep.spec import SweepSpec
from bowden.sweep.task import PEAK_PERCENT_ERROR_ABS

TENSION = "tension_rmse_n"
TENSION_RAISING = "tension_rmse_raising_n"
TENSION_LOWERING = "tension_rmse_lowering_n"
SPIKE = "lowering_peak_abs_pct"
SPIKE_SIGNED = "lowering_peak_pct"
SPIKE_TIME = "lowering_peak_time_pct"
ELEVATION = "elevation_rmse_deg"
RANK_TENSION = "rank_tension"
RANK_SPIKE = "rank_spike"
PARETO = "pareto"
PAPER_BLEND = "paper_blend"


def _phase_mean(results: pd.DataFrame, keys: list[str], phase: str, measure: str) -> pd.Series:
    rows = results[results["phase"] == phase]
    return rows.groupby(keys, sort=False)[measure].mean()


def summarize_points(results: pd.DataFrame, spec: SweepSpec) -> pd.DataFrame:
    """One row per configuration: its axis values, mean scores, ranks (1 = best), Pareto front.

    Sorted by tension RMSE. ``paper_blend`` marks configurations with the paper's −1/+1 rad/s blend.
    """
    if results.empty:
        raise ParameterError("the sweep has no results to summarise")
    columns = list(dict.fromkeys([ax.BLEND_01, ax.BLEND_99, *spec.axis_names]))
    first = results.drop_duplicates("config_id").set_index("config_id")[columns]
    table = first.copy()
    table[TENSION] = _phase_mean(results, ["config_id"], "entire", TENSION_RMSE)
    table[TENSION_RAISING] = _phase_mean(results, ["config_id"], "raising", TENSION_RMSE)
    table[TENSION_LOWERING] = _phase_mean(results, ["config_id"], "lowering", TENSION_RMSE)
    table[SPIKE] = _phase_mean(results, ["config_id"], "lowering", PEAK_PERCENT_ERROR_ABS)
    table[SPIKE_SIGNED] = _phase_mean(results, ["config_id"], "lowering", PEAK_PERCENT_ERROR)
    table[SPIKE_TIME] = _phase_mean(results, ["config_id"], "lowering", PEAK_PERCENT_ERROR_TIME)
    table[ELEVATION] = np.degrees(_phase_mean(results, ["config_id"], "entire", ELEVATION_RMSE))
    table["n_participants"] = results.groupby("config_id")[["seed", "participant"]].apply(
        lambda g: len(g.drop_duplicates())
    )
    table[RANK_TENSION] = table[TENSION].rank(method="min").astype("int64")
    table[RANK_SPIKE] = table[SPIKE].rank(method="min").astype("int64")
    table[PARETO] = pareto_front(table[TENSION].to_numpy(), table[SPIKE].to_numpy())
    table[PAPER_BLEND] = np.isclose(table[ax.BLEND_01], ax.PAPER_BLEND_01_RAD_S) & np.isclose(
        table[ax.BLEND_99], ax.PAPER_BLEND_99_RAD_S
    )
    return table.sort_values([TENSION, SPIKE]).reset_index()


def pareto_front(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """Boolean mask of the points not dominated in (``first``, ``second``), both minimised."""
    a = np.asarray(first, dtype=np.float64)
    b = np.asarray(second, dtype=np.float64)
    front = np.ones(a.size, dtype=bool)
    for i in range(a.size):
        dominated = (a <= a[i]) & (b <= b[i]) & ((a < a[i]) | (b < b[i]))
        front[i] = not bool(np.any(dominated))
    return front


def cell_optima(results: pd.DataFrame, *, measure: str, phase: str) -> pd.DataFrame:
    """Per condition and speed: the configuration with the lowest mean ``measure`` in ``phase``.

    Columns: condition, speed, the best configuration's blend velocities and score, and the score of
    the paper's blend when the sweep holds it (NaN otherwise).
    """
    rows = results[results["phase"] == phase]
    cells = rows.groupby(["condition", "speed", "config_id"], sort=False)[measure].mean().reset_index()
    blends = results.drop_duplicates("config_id").set_index("config_id")[[ax.BLEND_01, ax.BLEND_99]]
    paper = blends.index[
        np.isclose(blends[ax.BLEND_01], ax.PAPER_BLEND_01_RAD_S)
        & np.isclose(blends[ax.BLEND_99], ax.PAPER_BLEND_99_RAD_S)
    ]
    records = []
    for (condition, speed), group in cells.groupby(["condition", "speed"], sort=False):
        best = group.iloc[int(np.nanargmin(group[measure].to_numpy()))]
        paper_value = group[group["config_id"].isin(paper)][measure]
        records.append(
            {
                "condition": condition,
                "speed": speed,
                "config_id": best["config_id"],
                ax.BLEND_01: float(blends.loc[best["config_id"], ax.BLEND_01]),
                ax.BLEND_99: float(blends.loc[best["config_id"], ax.BLEND_99]),
                "best": float(best[measure]),
                "paper_blend": float(paper_value.mean()) if len(paper_value) else math.nan,
            }
        )
    return pd.DataFrame.from_records(records)


@dataclass(frozen=True)
class PairedDifference:
    """Mean over participants of (a − b) and its two-sided 95 % t-interval."""

    mean: float
    low: float
    high: float
    n: int


def paired_difference(
    results: pd.DataFrame, config_a: str, config_b: str, *, measure: str, phase: str
) -> PairedDifference:
    """Paired difference of two configurations, per participant (and seed) averaged over the cells."""
    rows = results[results["phase"] == phase]
    per = rows.groupby(["config_id", "seed", "participant"])[measure].mean()
    if config_a not in per.index.get_level_values(0) or config_b not in per.index.get_level_values(0):
        raise ParameterError(f"configuration {config_a!r} or {config_b!r} is not in the results")
    a, b = per.loc[config_a], per.loc[config_b]
    difference = (a - b).dropna().to_numpy()
    n = difference.size
    if n < 2:
        raise ParameterError("a paired difference needs at least two participants")
    mean = float(difference.mean())
    half = float(stats.t.ppf(0.975, n - 1) * difference.std(ddof=1) / math.sqrt(n))
    return PairedDifference(mean=mean, low=mean - half, high=mean + half, n=n)


def points_table(points: pd.DataFrame, axis_names: tuple[str, ...], *, top: int = 12) -> Table:
    """A rich table of the ``top`` configurations by tension RMSE, plus the paper's blend if lower."""
    shown = points.head(top)
    paper = points[points[PAPER_BLEND]]
    if not paper.empty and not bool(shown[PAPER_BLEND].any()):
        shown = pd.concat([shown, paper.head(1)])
    names = list(dict.fromkeys([ax.BLEND_01, ax.BLEND_99, *axis_names]))
    names = [n for n in names if n in shown.columns]
    table = Table(
        title=f"sweep: {len(points)} configurations, best {min(top, len(points))} by tension RMSE",
        caption="RMSE: tension, entire cycle; lower: lowering phase; |peak|: lowering peak % error",
    )
    short = {ax.BLEND_01: "θ̇01 rad/s", ax.BLEND_99: "θ̇99 rad/s"}
    for name in names:
        table.add_column(short.get(name, name), justify="right")
    for header in ("RMSE (N)", "lower (N)", "|peak| (%)", "at (%)", "rank", "spike"):
        table.add_column(header, justify="right")
    table.add_column("", justify="left")
    for _, row in shown.iterrows():
        marks = ("Pareto " if row[PARETO] else "") + ("paper" if row[PAPER_BLEND] else "")
        table.add_row(
            *[f"{row[n]:g}" for n in names],
            f"{row[TENSION]:.2f}",
            f"{row[TENSION_LOWERING]:.2f}",
            f"{row[SPIKE]:.1f}",
            f"{row[SPIKE_TIME]:.1f}",
            str(row[RANK_TENSION]),
            str(row[RANK_SPIKE]),
            marks.strip(),
        )
    return table
