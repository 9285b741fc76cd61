"""A study's report inputs without a simulation: outcome tables drawn from known distributions.

The report's tests need the shapes of a real study (every outcome the report shows, fitted
statistics, curves, questionnaire answers) but not its physics; drawing the values takes
milliseconds where simulating the trials takes minutes. The effects are chosen so that the report
meets what it must handle: an effect so strong that its p-value underflows (elevation RMSE), one with
no condition effect at all (SPARC: its pairwise cells read N/A), and one repetition per cell if asked.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from bowden import contracts as c
from bowden.analysis import MethodsText, methods_text
from bowden.analysis.outcomes import (
    ELEVATION_RMSE,
    IEMG_PREFIX,
    PEAK_PERCENT_ERROR,
    PEAK_PERCENT_ERROR_TIME,
    PERCENT_ERROR_RMSE,
    SPARC,
    TENSION_RMSE,
    TORQUE_RMSE,
    AnalysisInfo,
    AnalysisParameters,
    StudyOutcomes,
)
from bowden.analysis.segmentation import SegmentationParameters
from bowden.model import CompensationModel
from bowden.study.report.build import ReportInputs
from bowden.study.statistics import study_statistics

SUIT_MEASURES = (TENSION_RMSE, TORQUE_RMSE, PERCENT_ERROR_RMSE, PEAK_PERCENT_ERROR, PEAK_PERCENT_ERROR_TIME)


def _value(rng: np.random.Generator, measure: str, condition_index: int) -> float:
    if measure == ELEVATION_RMSE:  # a condition effect far beyond its noise: p underflows to ~0
        return float(np.radians(2.0 + 2.0 * condition_index) * rng.gamma(400.0, 1 / 400.0))
    if measure == SPARC:  # no condition effect: the pairwise cells read N/A
        return float(-3.0 * rng.gamma(50.0, 1 / 50.0))
    if measure == PEAK_PERCENT_ERROR_TIME:
        return float(rng.uniform(5.0, 95.0))
    return float((1.0 + 0.1 * condition_index) * rng.gamma(20.0, 1 / 20.0))


def outcome_table(n_participants: int, n_repetitions: int, seed: int = 0) -> pd.DataFrame:
    """Every measure the report shows, per participant, condition, speed, repetition and phase."""
    rng = np.random.default_rng(seed)
    rows = []
    trial_id = 0
    for p in range(1, n_participants + 1):
        for ci, condition in enumerate(c.CONDITIONS):
            measures = [ELEVATION_RMSE, SPARC, *(IEMG_PREFIX + m for m in c.MUSCLES)]
            if condition != "no_suit":
                measures += SUIT_MEASURES
            for speed in c.SPEEDS:
                trial_id += 1
                for repetition in range(1, n_repetitions + 1):
                    for phase in ("entire", "raising", "lowering"):
                        for measure in measures:
                            rows.append((f"P{p:02d}", condition, speed, trial_id, repetition, phase, measure,
                                         _value(rng, measure, ci)))
    return pd.DataFrame(rows, columns=["participant", "condition", "speed", "trial_id", "repetition", "phase",
                                       "measure", "value"])


def curves(participants: list[str], points: int = 11) -> pd.DataFrame:
    """Mean ± SD curves: elevation, torque and tension with each suit condition's own desired values."""
    tau = np.linspace(0.0, 1.0, points)
    frames = []
    for participant in participants:
        for ci, condition in enumerate(c.CONDITIONS):
            support = (0.0, 0.1, 0.25, 0.5)[ci]
            signals = {"elevation_rad": np.sin(np.pi * tau), "reference_elevation_rad": np.sin(np.pi * tau)}
            if condition != "no_suit":
                signals.update({
                    "desired_torque_nm": 10 * support * np.sin(np.pi * tau) + 0.5,
                    "torque_nm": 10 * support * np.sin(np.pi * tau) + 0.6,
                    "desired_tension_n": 200 * support * np.sin(np.pi * tau) + 10,
                    "tension_n": 200 * support * np.sin(np.pi * tau) + 12,
                })
            for speed in c.SPEEDS:
                for signal, mean in signals.items():
                    frames.append(pd.DataFrame({
                        "participant": participant, "condition": condition, "speed": speed, "signal": signal,
                        "normalised_time": tau, "mean": mean, "sd": 0.05, "n": 2,
                    }))
    return pd.concat(frames, ignore_index=True)


def answers(participants: list[str], seed: int = 0) -> pd.DataFrame:
    """Borg RPE falling with support (a Friedman p < 0.05 and a post-hoc) and a flat fatigue item."""
    rng = np.random.default_rng(seed)
    rows = []
    for participant in participants:
        for ci, condition in enumerate(c.CONDITIONS):
            rows.append((participant, condition, c.QUESTIONNAIRE_BORG_RPE, c.BORG_RPE_ITEM,
                         15 - 2 * ci + int(rng.integers(0, 2))))
            rows.append((participant, condition, c.QUESTIONNAIRE_FATIGUE, "deltoids", 3))
    return pd.DataFrame(rows, columns=["participant", "condition", "questionnaire", "item", "score"])


def report_inputs(
    *,
    n_participants: int = 4,
    n_repetitions: int = 2,
    drop_first: int = 1,
    model: CompensationModel | None = None,
    with_answers: bool = True,
    notes: tuple[str, ...] = (),
    methods: MethodsText | None = None,
) -> ReportInputs:
    """Report inputs of a drawn study (statistics fitted for real on the drawn values)."""
    outcomes = outcome_table(n_participants, n_repetitions)
    participants = sorted(set(outcomes["participant"]))
    given = answers(participants) if with_answers else pd.DataFrame()
    n_trials = int(outcomes["trial_id"].nunique())
    info = AnalysisInfo(
        parameters=AnalysisParameters(segmentation=SegmentationParameters(drop_first=drop_first)),
        n_trials=n_trials, n_participants=n_participants, n_repetitions=n_trials * n_repetitions,
        segmentation_sources={"reference": n_trials}, notes=notes, heart_rate_bpm={},
    )
    return ReportInputs(
        outcomes=StudyOutcomes(outcomes=outcomes, curves=curves(participants), info=info),
        statistics=study_statistics(outcomes, given),
        methods=methods if methods is not None else methods_text(info=info),
        model=model,
        simulated=True,
        n_participants=n_participants,
        n_trials=n_trials,
        questionnaires=given,
    )
