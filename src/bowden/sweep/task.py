"""The work of one sweep task, as pure functions that any Dask worker can run.

* :func:`identify_suit` — the simulated mannequin bench of one suit and the robust fit of its lines
  (``bowden study``'s bench and identify stages), giving the :class:`CompensationModel` that the
  points on that suit use.
* :func:`score_participant` — one participant of one point: every trial of the protocol simulated
  with the point's blend and suit, analysed with :func:`bowden.analysis.analyse_study` (the study's
  own outcome measures), and reduced to one row per (condition, speed, phase).

Both depend only on their arguments (the seeds included), so a task gives the same rows wherever and
however often it runs; that is what lets the runner retry a task whose worker died and skip a task
already on disk.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from bowden.analysis import AnalysisParameters, SegmentationParameters, TrialMetadata, analyse_study
from bowden.analysis.outcomes import (
    ELEVATION_RMSE,
    PEAK_PERCENT_ERROR,
    PEAK_PERCENT_ERROR_TIME,
    PERCENT_ERROR_RMSE,
    TENSION_RMSE,
    TORQUE_RMSE,
)
from bowden.contracts import PHASES
from bowden.identify import TransmissionIdentifier
from bowden.model import CompensationModel
from bowden.protocol.bench import QUICK_BENCH
from bowden.sim.batch import ProtocolSettings, simulate_trial, trial_seed
from bowden.sim.bench import BenchProtocol, run_bench
from bowden.sim.parameters import SuitParameters
from bowden.sim.participants import VirtualParticipant
from bowden.sweep import axes as ax
from bowden.sweep.spec import SweepPoint

# Scores of a row: the study's outcome measures, each the mean over the kept repetitions.
SCORE_MEASURES = (
    TENSION_RMSE,
    TORQUE_RMSE,
    PERCENT_ERROR_RMSE,
    PEAK_PERCENT_ERROR,
    PEAK_PERCENT_ERROR_TIME,
    ELEVATION_RMSE,
)
KEY_COLUMNS = ("config_id", "point_id", "seed", "participant", "condition", "speed", "phase")
AXIS_COLUMNS = (ax.BLEND_01, ax.BLEND_99, ax.BLEND_WIDTH, ax.BLEND_CENTER, *ax.PLANT_AXES)
MODEL_COLUMNS = (
    "model_raising_intercept_nm",
    "model_raising_slope_m",
    "model_lowering_intercept_nm",
    "model_lowering_slope_m",
)
# Mean over repetitions of |peak percent error|: the size of the spike whatever its sign, which the
# mean of signed peaks understates when repetitions disagree in sign.
PEAK_PERCENT_ERROR_ABS = "peak_percent_error_abs_pct"
SCORE_COLUMNS = (*SCORE_MEASURES, PEAK_PERCENT_ERROR_ABS)
RESULT_COLUMNS = (*KEY_COLUMNS, *AXIS_COLUMNS, *MODEL_COLUMNS, *SCORE_COLUMNS, "n_repetitions")


def bench_protocol(bench: str) -> BenchProtocol:
    """The identification protocol called ``bench`` (``"paper"`` or ``"quick"``)."""
    return QUICK_BENCH if bench == "quick" else BenchProtocol()


def identify_suit(suit: SuitParameters, bench: str, seed: int) -> CompensationModel:
    """Run the mannequin bench on ``suit`` and identify its compensation lines (paper's method)."""
    recording = run_bench(suit, bench_protocol(bench), seed=seed)
    model: CompensationModel = TransmissionIdentifier().fit(recording).model_
    return model


def controller_model(model: CompensationModel, point: SweepPoint) -> CompensationModel:
    """The identified lines with the point's blend velocities."""
    low, high = point.blend_velocities
    return replace(model, blend_velocity_01_rad_s=low, blend_velocity_99_rad_s=high)


def score_participant(
    point: SweepPoint,
    suit: SuitParameters,
    model: CompensationModel,
    participant: VirtualParticipant,
    participant_index: int,
    protocol: ProtocolSettings,
) -> pd.DataFrame:
    """Simulate and score every trial of one participant at one point.

    Parameters
    ----------
    point
        The point (its blend; ``suit`` already carries its plant values).
    suit
        The simulated suit of the point (before the wearer's own sheath routing, which
        :func:`bowden.sim.simulate_trial` applies).
    model
        The identified compensation lines; the point's blend replaces the model's.
    participant, participant_index
        Who, and the index in the cohort that seeds the trials (:func:`bowden.sim.trial_seed`).
    protocol
        Conditions, speeds and repetitions.

    Returns
    -------
    DataFrame with :data:`RESULT_COLUMNS`, one row per (condition, speed, phase): the mean over the
    kept repetitions (the first is dropped) of each outcome measure; ``peak_percent_error_pct`` and
    its time are NaN for the entire cycle (the paper gives them per phase).
    """
    controller = controller_model(model, point)
    trials = []
    for condition in protocol.conditions:
        for speed in protocol.speeds:
            trial = simulate_trial(
                participant,
                condition,
                speed,
                model=controller,
                suit=suit,
                settings=protocol,
                seed=trial_seed(point.seed, participant_index, condition, speed),
            )
            metadata = TrialMetadata(participant=participant.participant_id, condition=condition, speed=speed)
            trials.append((metadata, trial.to_pandas()))
    parameters = AnalysisParameters(
        segmentation=SegmentationParameters(expected_repetitions=protocol.repetitions)
    )
    outcomes = analyse_study(trials, parameters).outcomes
    return _rows(point, suit, controller, participant.participant_id, protocol, outcomes)


def _rows(
    point: SweepPoint,
    suit: SuitParameters,
    controller: CompensationModel,
    participant_id: str,
    protocol: ProtocolSettings,
    outcomes: pd.DataFrame,
) -> pd.DataFrame:
    scored = outcomes[outcomes["measure"].isin(SCORE_MEASURES)]
    means = scored.groupby(["condition", "speed", "phase", "measure"])["value"].mean()
    peaks = scored[scored["measure"] == PEAK_PERCENT_ERROR]
    abs_peaks = peaks["value"].abs().groupby([peaks["condition"], peaks["speed"], peaks["phase"]]).mean()
    counts = outcomes[outcomes["measure"] == ELEVATION_RMSE].groupby(["condition", "speed", "phase"]).size()
    low, high = point.blend_velocities
    constants = {
        "config_id": point.config_id,
        "point_id": point.point_id,
        "seed": point.seed,
        "participant": participant_id,
        ax.BLEND_01: low,
        ax.BLEND_99: high,
        ax.BLEND_WIDTH: high - low,
        ax.BLEND_CENTER: 0.5 * (low + high),
        **ax.plant_values(suit),
        "model_raising_intercept_nm": controller.raising.intercept_nm,
        "model_raising_slope_m": controller.raising.slope_m,
        "model_lowering_intercept_nm": controller.lowering.intercept_nm,
        "model_lowering_slope_m": controller.lowering.slope_m,
    }
    records = []
    for condition in protocol.conditions:
        for speed in protocol.speeds:
            for phase in PHASES:
                record: dict[str, object] = {
                    **constants, "condition": condition, "speed": speed, "phase": phase
                }
                for measure in SCORE_MEASURES:
                    record[measure] = float(means.get((condition, speed, phase, measure), np.nan))
                record[PEAK_PERCENT_ERROR_ABS] = float(abs_peaks.get((condition, speed, phase), np.nan))
                record["n_repetitions"] = int(counts.get((condition, speed, phase), 0))
                records.append(record)
    frame = pd.DataFrame.from_records(records, columns=list(RESULT_COLUMNS))
    return frame.astype({"seed": "int64", "n_repetitions": "int64"})
