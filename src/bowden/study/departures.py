"""Where a study's muscle activity departs from the paper's: direction, size and significance side by side.

For every muscle and phase the paper reports (its supplementary iEMG tables,
:mod:`bowden.study.paper_values.iemg`), the change of mean normalised iEMG from no suit to each suit
condition, averaged over the speeds, in this study and in the paper; flagged where the direction
differs (both changes at least a point from zero), where the size differs by more than
:data:`SIZE_TOLERANCE_POINTS`, or where the condition
effect is significant in one and not the other (p < 0.05).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from bowden import contracts as c
from bowden.analysis.outcomes import IEMG_PREFIX
from bowden.stats.analysis import OutcomeAnalysis
from bowden.study.paper_values.iemg_data import IEMG, IEMG_P
from bowden.study.statistics import MUSCLE_LABELS, StudyStatistics, outcome_data

SIZE_TOLERANCE_POINTS = 10.0  # percentage points: a change this close to the paper's is "the same size"
PHASES = ("entire", "raising", "lowering")
SUIT_CONDITIONS = (c.CONDITION_PRETENSION, c.CONDITION_SUPPORT_25, c.CONDITION_SUPPORT_50)


def _paper_change(phase: str, muscle: str, condition: str) -> float:
    base = {speed: IEMG[(phase, muscle, speed, c.CONDITION_NO_SUIT)][0] for speed in c.SPEEDS}
    changes = [IEMG[(phase, muscle, speed, condition)][0] / base[speed] - 1.0 for speed in c.SPEEDS]
    return 100.0 * float(np.mean(changes))


def _study_change(outcomes: pd.DataFrame, phase: str, muscle: str, condition: str) -> float:
    data = outcome_data(outcomes, IEMG_PREFIX + muscle, phase)
    if data.empty:
        return math.nan
    means = data.groupby(["condition", "speed"])["value"].mean()
    changes = []
    for speed in c.SPEEDS:
        base, value = means.get((c.CONDITION_NO_SUIT, speed)), means.get((condition, speed))
        if base is not None and value is not None and base > 0.0:
            changes.append(float(value) / float(base) - 1.0)
    return 100.0 * float(np.mean(changes)) if changes else math.nan


def _condition_p(fit: OutcomeAnalysis | None) -> float:
    if fit is None:
        return math.nan
    return float(fit.tests["p"].astype(float).get("condition", math.nan))


def iemg_departures(outcomes: pd.DataFrame, statistics: StudyStatistics) -> pd.DataFrame:
    """One row per phase, muscle and suit condition: the study's and the paper's change and the flags."""
    rows = []
    for phase in PHASES:
        fits = {fit.name: fit for fit in statistics.iemg.get(phase, [])}
        for muscle, label in MUSCLE_LABELS.items():
            study_p = _condition_p(fits.get(label))
            paper_p = IEMG_P[(phase, muscle)][0].value
            for condition in SUIT_CONDITIONS:
                ours = _study_change(outcomes, phase, muscle, condition)
                paper = _paper_change(phase, muscle, condition)
                flags = []
                if math.isfinite(ours):
                    # Changes within a point of zero have no direction to disagree about.
                    if min(abs(ours), abs(paper)) >= 1.0 and np.sign(ours) != np.sign(paper):
                        flags.append("direction")
                    if abs(ours - paper) > SIZE_TOLERANCE_POINTS:
                        flags.append("size")
                if math.isfinite(study_p) and (study_p < 0.05) != (paper_p < 0.05):
                    flags.append("significance")
                rows.append(
                    {
                        "phase": phase,
                        "muscle": label,
                        "condition": c.CONDITION_LABELS[condition],
                        "study change (%)": ours,
                        "paper change (%)": paper,
                        "study p (C)": study_p,
                        "paper p (C)": paper_p,
                        "departs in": ", ".join(flags) if math.isfinite(ours) else "no data",
                    }
                )
    return pd.DataFrame(rows)


def departure_summary(table: pd.DataFrame) -> str:
    """One sentence: how many comparisons agree, and which departures of direction there are."""
    usable = table[table["departs in"] != "no data"]
    if usable.empty:
        return "No iEMG in this study to compare with the paper."
    agree = int((usable["departs in"] == "").sum())
    wrong_way = usable[usable["departs in"].str.contains("direction")]
    named = "; ".join(
        f"{row['muscle']} {row['phase']} at {row['condition']} ({row['study change (%)']:+.0f} % against "
        f"{row['paper change (%)']:+.0f} %)"
        for _, row in wrong_way.iterrows()
    )
    text = (
        f"{agree} of {len(usable)} changes from no suit agree with the paper in direction, size (within "
        f"{SIZE_TOLERANCE_POINTS:g} points) and significance of the condition effect."
    )
    return text + (f" Opposite direction: {named}." if named else " None has the opposite direction.")
