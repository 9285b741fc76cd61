"""The report's tables built from the study's outcomes and fits, in the shapes of the paper's.

Each table of the study stands beside the paper's (:mod:`bowden.study.report.paper_tables`); these
functions make the study's side, the peak tables of both, and explain each cell left empty.
"""

from __future__ import annotations

import math

import pandas as pd

from bowden.analysis.outcomes import PEAK_PERCENT_ERROR, PEAK_PERCENT_ERROR_TIME, StudyOutcomes
from bowden.contracts import CONDITION_LABELS, CONDITIONS, SPEEDS
from bowden.model import CompensationModel
from bowden.stats.analysis import OutcomeAnalysis
from bowden.stats.tables import format_p
from bowden.study import paper_values


def tracking_table(outcomes: StudyOutcomes, measure: str) -> pd.DataFrame | None:
    data = outcomes.outcomes
    if data[data["measure"] == measure].empty:
        return None
    table = outcomes.rmse_table(measure)
    return table.drop(index=[c for c in table.index if c == "no_suit"], errors="ignore")


def side_by_side(ours: pd.DataFrame, paper: pd.DataFrame, label: str) -> pd.DataFrame:
    combined = pd.concat({label: ours, "paper": paper.reindex(columns=ours.columns)}, names=["source"])
    return combined.rename(index=CONDITION_LABELS, level="condition")


def beside(ours: pd.DataFrame, paper: pd.DataFrame, label: str) -> pd.DataFrame:
    """The study's table over the paper's, outcome by outcome, with a source level (study/paper)."""
    both = pd.concat({label: ours, "paper": paper.reindex(columns=ours.columns)}, names=["source"])
    outcomes = list(dict.fromkeys(ours.index.get_level_values(0)))
    order = sorted(range(len(both)), key=lambda i: (
        outcomes.index(both.index[i][1]) if both.index[i][1] in outcomes else len(outcomes),
        both.index[i][0] != label,
    ))
    return both.iloc[order].reorder_levels([1, 0, *range(2, both.index.nlevels)])


def mean_sd_text(values: list[float]) -> str:
    """``"mean (SD)"``; one value has no SD and reads ``"12.3 (n = 1)"``; none reads ``"–"``."""
    if not values:
        return "–"
    if len(values) == 1:
        return f"{values[0]:.1f} (n = 1)"
    return f"{pd.Series(values).mean():.1f} ({pd.Series(values).std(ddof=1):.1f})"


def peak_table(outcomes: pd.DataFrame, phase: str) -> pd.DataFrame | None:
    """Mean (SD) over participants and repetitions of the peak percent error and its time, per speed
    (a cell of one repetition shows its value: a study of one participant and repetition has no SD)."""
    rows = {}
    for condition in CONDITIONS[1:]:
        cells = {}
        for speed in SPEEDS:
            for measure, name in (
                (PEAK_PERCENT_ERROR, "peak error (%)"),
                (PEAK_PERCENT_ERROR_TIME, "time (%)"),
            ):
                values = outcomes[
                    (outcomes["measure"] == measure)
                    & (outcomes["phase"] == phase)
                    & (outcomes["condition"] == condition)
                    & (outcomes["speed"] == speed)
                ]["value"].dropna()
                cells[(speed, name)] = mean_sd_text(values.to_list())
        rows[CONDITION_LABELS[condition]] = cells
    table = pd.DataFrame.from_dict(rows, orient="index")
    if (table == "–").all().all():
        return None
    table.columns = pd.MultiIndex.from_tuples(
        [tuple(col) for col in table.columns], names=["speed", "quantity"]
    )
    return table


def paper_peak_table(phase: str) -> pd.DataFrame:
    paper = paper_values.peak_percent_error(phase)
    rows = {}
    for condition in paper.index:
        cells = {}
        for speed in SPEEDS:
            p = paper.loc[condition, speed]
            cells[(speed, "peak error (%)")] = f"{p['peak_error_pct']:.1f} ({p['peak_error_sd']:.1f})"
            cells[(speed, "time (%)")] = f"{p['normalised_time_pct']:.1f} ({p['normalised_time_sd']:.1f})"
        rows[CONDITION_LABELS[condition]] = cells
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.columns = pd.MultiIndex.from_tuples(
        [tuple(col) for col in table.columns], names=["speed", "quantity"]
    )
    return table


def model_table(model: CompensationModel) -> pd.DataFrame:
    rows = []
    for name, line, fit in (
        ("raising", model.raising, model.raising_fit),
        ("lowering", model.lowering, model.lowering_fit),
    ):
        rows.append(
            {
                "line": name,
                "intercept (Nm)": line.intercept_nm,
                "slope (mm)": 1000.0 * line.slope_m,
                "R² (fitlm robust)": fit.r_squared_robust if fit else math.nan,
                "R² (OLS, corr²)": fit.r_squared_ols if fit else math.nan,
                "n": fit.n if fit else math.nan,
            }
        )
    return pd.DataFrame(rows).set_index("line")


def condition_comparisons(analysis: OutcomeAnalysis | None) -> list[tuple[str, str, float]]:
    """(condition, condition, Holm p) over the speeds grouped, where the condition effect has p < 0.05."""
    if analysis is None:
        return []
    condition_p = analysis.tests["p"].astype(float).get("condition", float("nan"))
    if not condition_p < 0.05:
        return []
    pairs = analysis.condition_pairs
    return [
        (str(a), str(b), float(p))
        for a, b, p in zip(pairs["level_a"], pairs["level_b"], pairs["p_holm"], strict=True)
    ]


_FACTOR_CODES = {"condition": "C", "speed": "V"}


def explain_not_compared(table: pd.DataFrame, analyses: list[OutcomeAnalysis], factor: str) -> pd.DataFrame:
    """A :func:`bowden.stats.pairwise_table` whose ``N/A`` cells say why: ``N/A (p (C) = 0.231)``,
    the factor's Type-III p that was not below 0.05, so that (as in the paper) no pair was compared."""
    code = _FACTOR_CODES[factor]
    table = table.copy()
    for analysis in analyses:
        if analysis.name not in table.index:
            continue
        p = float(analysis.tests["p"].astype(float).get(factor, math.nan))
        reason = f"N/A (p ({code}) = {format_p(p)})" if math.isfinite(p) else f"N/A (no test of {code})"
        for column in table.columns:
            if table.at[analysis.name, column] == "N/A":
                table.at[analysis.name, column] = reason
    return table
