"""The per-point task, in process: its rows against scores computed by hand from the simulated trials."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest

from bowden import contracts as c
from bowden.analysis import SegmentationParameters, segment_repetitions
from bowden.model.transmission import slopes_from_friction
from bowden.sim import simulate_trial
from bowden.sim.batch import trial_seed
from bowden.sim.parameters import SuitParameters
from bowden.sweep import (
    RESULT_COLUMNS,
    SweepSpec,
    cohort,
    identify_suit,
    protocol_settings,
    score_participant,
)
from bowden.sweep import axes as ax
from bowden.sweep.task import controller_model

SUIT = SuitParameters()


@pytest.fixture(scope="module")
def model():
    return identify_suit(SUIT, "quick", 0)


@pytest.fixture(scope="module")
def spec():
    return SweepSpec(
        axes=((ax.BLEND_01, (-1.0, -0.1)), (ax.BLEND_99, (0.5, 1.0))),
        participants=2,
        repetitions=3,
        conditions=("support_50",),
        speeds=("V1", "V3"),
        bench="quick",
    )


def test_rows_are_the_mean_over_kept_repetitions_of_hand_computed_errors(spec, model):
    point = spec.points()[1]  # θ̇₀₀₁ = −1, θ̇₀₉₉ = +1: the paper's blend
    assert point.blend_velocities == (-1.0, 1.0)
    participant = cohort(spec, point.seed)[1]
    protocol = protocol_settings(spec)
    frame = score_participant(point, SUIT, model, participant, 1, protocol)
    assert tuple(frame.columns) == RESULT_COLUMNS
    assert len(frame) == 1 * 2 * 3  # conditions × speeds × phases
    assert (frame["n_repetitions"] == 2).all()  # three cycles, the first dropped
    for speed in spec.speeds:
        trial = simulate_trial(
            participant,
            "support_50",
            speed,
            model=controller_model(model, point),
            suit=SUIT,
            settings=protocol,
            seed=trial_seed(point.seed, 1, "support_50", speed),
        )
        data = trial.to_pandas()
        time = data[c.TRIAL_TIME].to_numpy()
        tension = data[c.TRIAL_TENSION].to_numpy()
        desired = data[c.TRIAL_DESIRED_TENSION].to_numpy()
        reps = segment_repetitions(data, SegmentationParameters(expected_repetitions=3)).repetitions
        entire, lowering, peaks = [], [], []
        for rep in reps:
            inside = (time >= rep.start_s) & (time <= rep.end_s)
            down = (time >= rep.turn_s) & (time <= rep.end_s)
            entire.append(math.sqrt(np.mean((tension[inside] - desired[inside]) ** 2)))
            lowering.append(math.sqrt(np.mean((tension[down] - desired[down]) ** 2)))
            percent = 100.0 * (tension[down] - desired[down]) / desired[down]
            peaks.append(percent[np.argmax(np.abs(percent))])
        rows = frame[frame["speed"] == speed].set_index("phase")
        assert rows.loc["entire", "tension_rmse_n"] == pytest.approx(np.mean(entire), rel=1e-12)
        assert rows.loc["lowering", "tension_rmse_n"] == pytest.approx(np.mean(lowering), rel=1e-12)
        assert rows.loc["lowering", "peak_percent_error_pct"] == pytest.approx(np.mean(peaks), rel=1e-12)
        assert rows.loc["lowering", "peak_percent_error_abs_pct"] == pytest.approx(
            np.mean(np.abs(peaks)), rel=1e-12
        )
        assert math.isnan(rows.loc["entire", "peak_percent_error_pct"])
    # The row carries the point: blend, plant values, identified lines.
    assert (frame[ax.BLEND_01] == -1.0).all() and (frame[ax.BLEND_99] == 1.0).all()
    assert (frame[ax.BLEND_WIDTH] == 2.0).all() and (frame[ax.BLEND_CENTER] == 0.0).all()
    assert (frame[ax.SHEATH_KINETIC] == SUIT.sheath.kinetic_coefficient).all()
    assert (frame["model_raising_slope_m"] == model.raising.slope_m).all()
    assert (frame["participant"] == participant.participant_id).all()


def test_same_arguments_give_identical_rows(spec, model):
    point = spec.points()[0]
    participant = cohort(spec, point.seed)[0]
    protocol = protocol_settings(spec)
    first = score_participant(point, SUIT, model, participant, 0, protocol)
    second = score_participant(point, SUIT, model, participant, 0, protocol)
    pd.testing.assert_frame_equal(first, second)


def test_a_narrow_blend_beats_the_papers_at_the_slow_speed(spec, model):
    # At V1 the elevation speed peaks at 1.05 rad/s: with the paper's ±1 rad/s blend the controller
    # sits between its two lines for most of the movement, a 0.6 rad/s blend commits to the right one.
    protocol = protocol_settings(spec)
    # A steady participant (little motor noise, no wandering lag): the blend's effect, not the noise's.
    participant = dataclasses.replace(cohort(spec, 0)[0], motor_noise_nm=0.1, lag_wander_sd=0.0)
    by_blend = {p.blend_velocities: p for p in spec.points()}
    narrow = score_participant(by_blend[(-0.1, 0.5)], SUIT, model, participant, 0, protocol)
    paper = score_participant(by_blend[(-1.0, 1.0)], SUIT, model, participant, 0, protocol)

    def entire_v1(frame: pd.DataFrame) -> float:
        return float(frame[(frame["speed"] == "V1") & (frame["phase"] == "entire")]["tension_rmse_n"].iloc[0])

    assert entire_v1(narrow) < 0.8 * entire_v1(paper)


def test_controller_model_changes_the_blend_only(spec, model):
    point = spec.points()[0]
    controller = controller_model(model, point)
    assert (controller.blend_velocity_01_rad_s, controller.blend_velocity_99_rad_s) == (-1.0, 0.5)
    assert controller.raising == model.raising and controller.lowering == model.lowering
    assert controller.blend_weight(-1.0) == pytest.approx(0.01)
    assert controller.blend_weight(0.5) == pytest.approx(0.99)


def test_identification_per_suit_absorbs_the_torque_constant():
    # The bench logs the torque the driver reports (the commanded one); the motor delivers
    # ratio × that, so the identified slopes are the plant's R(1±k)/(1∓k) divided by the ratio.
    ratio = 0.8
    suit = ax.apply_plant(SUIT, {ax.TORQUE_CONSTANT_RATIO: ratio})
    weak = identify_suit(suit, "quick", 0)
    raising, lowering = slopes_from_friction(SUIT.sheath.kinetic_coefficient, SUIT.motor.spool_radius_m)
    assert weak.raising.slope_m == pytest.approx(raising / ratio, rel=0.01)
    assert weak.lowering.slope_m == pytest.approx(lowering / ratio, rel=0.01)
