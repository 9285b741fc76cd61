"""Elevation RMSE and SPARC beside the paper's Tables S4-S6.

Per outcome: the significance of the condition and speed effects (S4); the change from no suit of each
suit condition, in percent of the no-suit mean averaged over the speeds (S4's means); the pairwise
condition comparisons of SPARC (S5) and the speed comparisons (S6), in direction, size and
significance. The elevation RMSE's level per speed is what the participants' visuomotor lag was tuned
to (calibrated, :mod:`bowden.study.departures.calibration`).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from bowden import contracts as c
from bowden.analysis.outcomes import ELEVATION_RMSE, SPARC
from bowden.stats.analysis import OutcomeAnalysis
from bowden.study.departures.rows import Tolerance, comparison_row, frame
from bowden.study.paper_values.kinematics_data import (
    KINEMATICS,
    KINEMATICS_CONDITION_PAIRS,
    KINEMATICS_P,
    KINEMATICS_SPEED_PAIRS,
)
from bowden.study.statistics import KINEMATIC_LABELS, StudyStatistics, outcome_data

# measure -> (paper's key, name, unit, tolerance of a change from no suit in %, of a pairwise change)
OUTCOMES = {
    ELEVATION_RMSE: ("elevation_rmse_deg", "elevation RMSE", "deg", Tolerance(10.0, dead_zone=1.0),
                     Tolerance(2.0, dead_zone=0.1)),
    SPARC: ("sparc", "SPARC", "", Tolerance(2.0, dead_zone=0.5), Tolerance(0.05, dead_zone=0.005)),
}
LEVEL_TOLERANCE_DEG = Tolerance(1.5, direction=False)
SUIT = (c.CONDITION_PRETENSION, c.CONDITION_SUPPORT_25, c.CONDITION_SUPPORT_50)


def _pairs(fit: OutcomeAnalysis | None, factor: str) -> dict[tuple[str, str], tuple[float, float]]:
    if fit is None:
        return {}
    pairs = fit.condition_pairs if factor == "condition" else fit.speed_pairs
    return {
        (str(a), str(b)): (float(e), float(p))
        for a, b, e, p in zip(pairs["level_a"], pairs["level_b"], pairs["estimate"], pairs["p_holm"],
                              strict=True)
    }


def _term_p(fit: OutcomeAnalysis | None, term: str) -> float:
    if fit is None:
        return math.nan
    return float(fit.tests["p"].astype(float).get(term, math.nan))


def kinematics_departures(outcomes: pd.DataFrame, statistics: StudyStatistics) -> pd.DataFrame:
    fits = {fit.name: fit for fit in statistics.kinematics}
    rows = []
    for measure, (key, name, unit, change_tol, pair_tol) in OUTCOMES.items():
        fit = fits.get(KINEMATIC_LABELS[measure])
        data = outcome_data(outcomes, measure, "entire")
        means = data.groupby(["condition", "speed"])["value"].mean() if not data.empty else pd.Series()
        for index, term in enumerate(("condition", "speed")):
            rows.append(comparison_row(
                family="kinematics", outcome=f"{name}, {term} effect", comparison="GLMM", unit="",
                study=math.nan, paper=math.nan, tolerance=Tolerance(math.nan),
                study_p=_term_p(fit, term), paper_p=KINEMATICS_P[key][index],
            ))
        for condition in SUIT:
            study, paper = [], []
            for speed in c.SPEEDS:
                base, value = means.get((c.CONDITION_NO_SUIT, speed)), means.get((condition, speed))
                if base is not None and value is not None:
                    study.append(float(value) / float(base) - 1.0)
                paper_mean = KINEMATICS[(key, speed, condition)][0]
                paper.append(paper_mean / KINEMATICS[(key, speed, c.CONDITION_NO_SUIT)][0] - 1.0)
            rows.append(comparison_row(
                family="kinematics", outcome=f"{name}, change from no suit", unit="%",
                comparison=f"{c.CONDITION_LABELS[condition]}-no",
                study=100.0 * float(np.mean(study)) if study else math.nan,
                paper=100.0 * float(np.mean(paper)), tolerance=change_tol,
            ))
        if measure == ELEVATION_RMSE:
            for speed in c.SPEEDS:
                value = means.get((c.CONDITION_NO_SUIT, speed))
                rows.append(comparison_row(
                    family="kinematics", outcome="elevation RMSE, level without the suit", unit="deg",
                    comparison=speed, study=float(value) if value is not None else math.nan,
                    paper=KINEMATICS[(key, speed, "no_suit")][0], tolerance=LEVEL_TOLERANCE_DEG,
                ))
        for factor, published, label in (
            ("condition", KINEMATICS_CONDITION_PAIRS, "conditions compared (S5)"),
            ("speed", KINEMATICS_SPEED_PAIRS, "speeds compared (S6)"),
        ):
            fitted = _pairs(fit, factor)
            # The elevation RMSE between speeds is set by the tuned lag: named as a level (calibrated).
            between_speeds = measure == ELEVATION_RMSE and factor == "speed"
            outcome = f"{name}, levels between speeds (S6)" if between_speeds else f"{name}, {label}"
            for (outcome_key, first, second), (change, _, paper_p) in published.items():
                if outcome_key != key:
                    continue
                estimate, study_p = fitted.get((first, second), (math.nan, math.nan))
                names = c.CONDITION_LABELS
                rows.append(comparison_row(
                    family="kinematics", outcome=outcome, unit=unit,
                    comparison=f"{names.get(first, first)}-{names.get(second, second)}",
                    study=estimate, paper=change, tolerance=pair_tol, study_p=study_p, paper_p=paper_p,
                ))
    return frame(rows)
