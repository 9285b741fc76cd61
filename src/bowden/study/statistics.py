"""The paper's statistics on a study's outcome table and questionnaires.

GLMMs (gamma, log link, condition × speed, random intercept per participant; SPSS-like PQL-REML) for
iEMG of each muscle and phase, elevation RMSE and SPARC, on repetition-level values as the paper's
SPSS models; Friedman tests with MATLAB's Bonferroni post-hoc for every questionnaire item.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from bowden.analysis.outcomes import ELEVATION_RMSE, IEMG_PREFIX, SPARC
from bowden.contracts import CONDITIONS, MUSCLES
from bowden.errors import BowdenError
from bowden.stats import OutcomeAnalysis, analyse_outcome, friedman_multcompare, friedman_test

MUSCLE_LABELS = {
    "anterior_deltoid": "Ant. delt.",
    "medial_deltoid": "Med. delt.",
    "posterior_deltoid": "Post. delt.",
    "biceps": "Biceps",
    "triceps": "Triceps",
    "trapezius": "Trapezius",
    "latissimus_dorsi": "Lat. dorsi",
    "pectoralis_major": "Pect. major",
}
KINEMATIC_LABELS = {ELEVATION_RMSE: "RMSE (deg)", SPARC: "SPARC (-)"}


@dataclass
class StudyStatistics:
    """Fitted outcome models and questionnaire tests; ``failures`` names models that could not be fitted."""

    kinematics: list[OutcomeAnalysis] = field(default_factory=list)
    iemg: dict[str, list[OutcomeAnalysis]] = field(default_factory=dict)  # by phase
    questionnaires: pd.DataFrame = field(default_factory=pd.DataFrame)
    questionnaire_posthoc: dict[str, pd.DataFrame] = field(default_factory=dict)
    failures: list[str] = field(default_factory=list)


def outcome_data(outcomes: pd.DataFrame, measure: str, phase: str) -> pd.DataFrame:
    """Repetition-level values of one measure and phase, in the units and signs of the paper.

    Elevation RMSE in degrees; SPARC with its sign flipped to positive as the paper reports it (a
    gamma model needs positive values).
    """
    data = outcomes[(outcomes["measure"] == measure) & (outcomes["phase"] == phase)]
    data = data.loc[:, ["participant", "condition", "speed", "value"]].dropna()
    if measure == ELEVATION_RMSE:
        data = data.assign(value=np.degrees(data["value"]))
    elif measure == SPARC:
        data = data.assign(value=-data["value"])
    return data.reset_index(drop=True)


FitJob = tuple[pd.DataFrame, str]
FitResult = tuple[OutcomeAnalysis | None, str | None]
# How the fits are run: ``map`` here, or an engine's ordered map over worker processes.
FitMapper = Callable[[Callable[[FitJob], FitResult], Iterable[FitJob]], Iterable[FitResult]]


def fit_outcome(job: FitJob) -> FitResult:
    """One outcome's model, or why it could not be fitted (module level, so that workers can run it)."""
    data, name = job
    if data.empty or data["condition"].nunique() < 2:
        return None, f"{name}: not enough data"
    try:
        return analyse_outcome(data, name), None
    except BowdenError as error:
        return None, f"{name}: {error}"


def study_statistics(
    outcomes: pd.DataFrame, questionnaires: pd.DataFrame, *, mapper: FitMapper = map
) -> StudyStatistics:
    """Fit every model of the paper that the data allows.

    The fits are independent: ``mapper`` may run them in parallel, provided it gives the results in
    the order of the jobs (then the statistics do not depend on it).
    """
    stats = StudyStatistics()
    jobs: list[tuple[str, FitJob]] = [
        ("kinematics", (outcome_data(outcomes, measure, "entire"), label))
        for measure, label in KINEMATIC_LABELS.items()
    ]
    for phase in ("raising", "lowering", "entire"):
        stats.iemg[phase] = []
        jobs += [
            (phase, (outcome_data(outcomes, IEMG_PREFIX + muscle, phase), MUSCLE_LABELS[muscle]))
            for muscle in MUSCLES
        ]
    results = mapper(fit_outcome, [job for _group, job in jobs])
    for (group, _job), (fitted, failure) in zip(jobs, results, strict=True):
        if failure is not None:
            stats.failures.append(failure)
        elif fitted is not None:
            (stats.kinematics if group == "kinematics" else stats.iemg[group]).append(fitted)
    stats.questionnaires, stats.questionnaire_posthoc = questionnaire_tests(questionnaires)
    return stats


def questionnaire_tests(answers: pd.DataFrame) -> tuple[pd.DataFrame, dict[str, pd.DataFrame]]:
    """Friedman per questionnaire item across conditions; Bonferroni post-hoc where p < 0.05.

    Returns a table (questionnaire, item, median per condition, chi², p) and the post-hoc tables by
    ``"questionnaire/item"``.
    """
    rows, posthoc = [], {}
    if answers.empty:
        return pd.DataFrame(), {}
    for (questionnaire, item), group in answers.groupby(["questionnaire", "item"], sort=False):
        data = group.rename(columns={"score": "value"})
        medians = data.groupby("condition")["value"].median()
        row: dict[str, object] = {"questionnaire": questionnaire, "item": item}
        row.update({f"median {c}": float(medians.get(c, math.nan)) for c in CONDITIONS})
        try:
            result = friedman_test(data)
        except BowdenError as error:
            row.update({"chi2": math.nan, "p": math.nan, "note": str(error)})
            rows.append(row)
            continue
        # All scores equal: no ranking information (the paper's floor effects).
        p = result.p if math.isfinite(result.p) else 1.0
        row.update({"chi2": result.statistic, "p": p, "note": ""})
        rows.append(row)
        if p < 0.05:
            posthoc[f"{questionnaire}/{item}"] = friedman_multcompare(result)
    return pd.DataFrame(rows), posthoc
