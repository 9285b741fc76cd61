"""The questionnaires beside the paper's Results text (the only place it gives their numbers).

Every item with a published Friedman p is compared in significance; the Nordic neck and shoulder items
also in direction (the change of the median from no suit to 50 % support; the paper: an increase), and
each post-hoc comparison the text reports in direction and, where the study ran its post-hoc test, in
significance. The paper publishes no medians as numbers (its figures are images), so sizes are not
compared.
"""

from __future__ import annotations

import math

import pandas as pd

from bowden import contracts as c
from bowden.study.departures.rows import Tolerance, comparison_row, frame
from bowden.study.paper_values.questionnaire_data import NORDIC_PAIRS, QUESTIONNAIRE_P
from bowden.study.statistics import StudyStatistics

NAMES = {
    c.QUESTIONNAIRE_NORDIC: "Nordic", c.QUESTIONNAIRE_BORG_RPE: "RPE", c.QUESTIONNAIRE_FATIGUE: "fatigue",
}
DIRECTION = Tolerance(math.nan, dead_zone=0.0)


def _median_change(row: pd.Series | None, first: str, second: str) -> float:
    """Median of ``second`` minus median of ``first`` (points), from the Friedman table's row."""
    if row is None:
        return math.nan
    return float(row.get(f"median {second}", math.nan)) - float(row.get(f"median {first}", math.nan))


def _posthoc_p(statistics: StudyStatistics, item: str, first: str, second: str) -> float:
    table = statistics.questionnaire_posthoc.get(f"{c.QUESTIONNAIRE_NORDIC}/{item}")
    if table is None:
        return math.nan
    match = table[((table["group_a"] == first) & (table["group_b"] == second))
                  | ((table["group_a"] == second) & (table["group_b"] == first))]
    return float(match["p"].iloc[0]) if not match.empty else math.nan


def questionnaire_departures(statistics: StudyStatistics) -> pd.DataFrame:
    tests = statistics.questionnaires
    found: dict[tuple[str, str], pd.Series] = {}
    if not tests.empty:
        found = {(str(r["questionnaire"]), str(r["item"])): r for _, r in tests.iterrows()}
    rows = []
    for (questionnaire, item), paper_p in QUESTIONNAIRE_P.items():
        row = found.get((questionnaire, item))
        outcome = f"{NAMES[questionnaire]} {item.replace('_', ' ')}"
        nordic = questionnaire == c.QUESTIONNAIRE_NORDIC
        rows.append(comparison_row(
            family="questionnaires", outcome=outcome, comparison="50%-no (median), Friedman p",
            unit="points", tolerance=DIRECTION,
            study=_median_change(row, c.CONDITION_NO_SUIT, c.CONDITION_SUPPORT_50),
            paper="increase" if nordic else "no change",
            study_p=float(row["p"]) if row is not None else math.nan, paper_p=paper_p,
        ))
    for (item, first, second), (direction, paper_p) in NORDIC_PAIRS.items():
        posthoc_p = _posthoc_p(statistics, item, first, second)
        rows.append(comparison_row(
            family="questionnaires", outcome=f"Nordic {item.replace('_', ' ')}, post-hoc",
            comparison=f"{c.CONDITION_LABELS[second]}-{c.CONDITION_LABELS[first]} (median)", unit="points",
            study=_median_change(found.get((c.QUESTIONNAIRE_NORDIC, item)), first, second),
            paper=direction, tolerance=DIRECTION, study_p=posthoc_p, paper_p=paper_p,
        ))
    return frame(rows)
