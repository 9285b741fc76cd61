"""Where a study departs from the paper: every outcome the paper reports, side by side with the study's.

:func:`all_departures` gathers the families — tension and torque tracking and peak errors
(:mod:`bowden.study.departures.tracking`), elevation RMSE and SPARC
(:mod:`bowden.study.departures.kinematics`), iEMG (here) and the questionnaires
(:mod:`bowden.study.departures.questionnaires`) — as rows of :mod:`bowden.study.departures.rows`.

iEMG: for every muscle and phase of the paper's Tables S7-S12, the significance of the condition
effect, and for every pair of conditions the change in percent (the study's GLMM pairwise estimate, or
without a fit the change of the means averaged over the speeds) against Tables S10-S12, within
:data:`SIZE_TOLERANCE_POINTS`.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from bowden import contracts as c
from bowden.analysis.outcomes import IEMG_PREFIX
from bowden.stats.analysis import OutcomeAnalysis
from bowden.study.departures.calibration import CALIBRATED
from bowden.study.departures.kinematics import kinematics_departures
from bowden.study.departures.questionnaires import questionnaire_departures
from bowden.study.departures.rows import Tolerance, comparison_row, frame
from bowden.study.departures.tracking import tracking_departures
from bowden.study.paper_values.iemg_data import IEMG_P, IEMG_PAIRS
from bowden.study.statistics import MUSCLE_LABELS, StudyStatistics, outcome_data

SIZE_TOLERANCE_POINTS = 10.0  # percentage points: a change this close to the paper's is "the same size"
IEMG_TOLERANCE = Tolerance(size=SIZE_TOLERANCE_POINTS, dead_zone=1.0)
PHASES = ("entire", "raising", "lowering")
NAMED_AT_MOST = 12  # opposite directions named in the summary sentence; the table has them all
PAIRS = tuple(dict.fromkeys((a, b) for (_, _, a, b) in IEMG_PAIRS))


def pair_label(first: str, second: str) -> str:
    """``"50%-no"``: the paper's name of a comparison (first minus second)."""
    return f"{c.CONDITION_LABELS[first]}-{c.CONDITION_LABELS[second]}"


def _mean_change(outcomes: pd.DataFrame, phase: str, muscle: str, first: str, second: str) -> float:
    data = outcome_data(outcomes, IEMG_PREFIX + muscle, phase)
    if data.empty:
        return math.nan
    means = data.groupby(["condition", "speed"])["value"].mean()
    changes = []
    for speed in c.SPEEDS:
        base, value = means.get((second, speed)), means.get((first, speed))
        if base is not None and value is not None and base > 0.0:
            changes.append(float(value) / float(base) - 1.0)
    return 100.0 * float(np.mean(changes)) if changes else math.nan


def _fitted_pairs(fit: OutcomeAnalysis | None) -> dict[tuple[str, str], tuple[float, float]]:
    if fit is None:
        return {}
    pairs = fit.condition_pairs
    return {
        (str(a), str(b)): (float(pct), float(p))
        for a, b, pct, p in zip(
            pairs["level_a"], pairs["level_b"], pairs["percent_change"], pairs["p_holm"], strict=True
        )
    }


def _condition_p(fit: OutcomeAnalysis | None) -> float:
    if fit is None:
        return math.nan
    return float(fit.tests["p"].astype(float).get("condition", math.nan))


def iemg_departures(outcomes: pd.DataFrame, statistics: StudyStatistics) -> pd.DataFrame:
    """Per phase and muscle: the condition effect, then every pair of conditions (Tables S7-S12)."""
    rows = []
    for phase in PHASES:
        fits = {fit.name: fit for fit in statistics.iemg.get(phase, [])}
        for muscle, label in MUSCLE_LABELS.items():
            fit = fits.get(label)
            outcome = f"{label}, {phase}"
            rows.append(comparison_row(
                family="iEMG", outcome=outcome, comparison="condition effect", unit="",
                study=math.nan, paper=math.nan, tolerance=Tolerance(math.nan),
                study_p=_condition_p(fit), paper_p=IEMG_P[(phase, muscle)][0],
            ))
            fitted = _fitted_pairs(fit)
            for first, second in PAIRS:
                _, paper_pct, paper_p = IEMG_PAIRS[(phase, muscle, first, second)]
                if (first, second) in fitted:
                    study_pct, study_p = fitted[(first, second)]
                else:  # no model: the raw change of the means, without a p
                    study_pct, study_p = _mean_change(outcomes, phase, muscle, first, second), math.nan
                rows.append(comparison_row(
                    family="iEMG", outcome=outcome, comparison=pair_label(first, second), unit="%",
                    study=study_pct, paper=paper_pct, tolerance=IEMG_TOLERANCE,
                    study_p=study_p, paper_p=paper_p,
                ))
    return frame(rows)


def all_departures(outcomes: pd.DataFrame, statistics: StudyStatistics) -> pd.DataFrame:
    """Every family's rows, tracking first (the paper's order)."""
    parts = [
        tracking_departures(outcomes),
        kinematics_departures(outcomes, statistics),
        iemg_departures(outcomes, statistics),
        questionnaire_departures(statistics),
    ]
    return pd.concat([part for part in parts if not part.empty] or [frame([])], ignore_index=True)


def family_summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per family: rows compared, agreeing, departing (evidence only), calibrated, without data."""
    records = {}
    for family, group in table.groupby("family", sort=False):
        usable = group[group["departs in"] != "no data"]
        evidence = usable[usable["evidence"] != CALIBRATED]
        records[family] = {
            "compared": len(usable),
            "agree": int((evidence["departs in"] == "").sum()),
            "depart": int((evidence["departs in"] != "").sum()),
            "calibrated (not evidence)": len(usable) - len(evidence),
            "no data": len(group) - len(usable),
        }
    return pd.DataFrame.from_dict(records, orient="index").rename_axis("family")


def departure_summary(table: pd.DataFrame) -> str:
    """Sentences: how many comparisons that are evidence agree, and which go the other way."""
    usable = table[(table["departs in"] != "no data") & (table["evidence"] != CALIBRATED)]
    if usable.empty:
        return "Nothing in this study to compare with the paper."
    agree = int((usable["departs in"] == "").sum())
    wrong_way = usable[usable["departs in"].str.contains("direction")]

    def value(v: object) -> str:
        return f"{v:+.3g}" if isinstance(v, float) else str(v)

    named = "; ".join(
        f"{row['outcome']} {row['comparison']} ({value(row['study'])} against {value(row['paper'])}"
        f"{' ' + row['unit'] if row['unit'] else ''})"
        for _, row in wrong_way.head(NAMED_AT_MOST).iterrows()
    )
    if len(wrong_way) > NAMED_AT_MOST:
        named += f"; and {len(wrong_way) - NAMED_AT_MOST} more (in the table below)"
    text = (
        f"{agree} of {len(usable)} comparisons that are evidence (not calibrated) agree with the paper in "
        "direction, size (within each family's tolerance) and significance."
    )
    return text + (f" Opposite direction: {named}." if named else " None has the opposite direction.")
