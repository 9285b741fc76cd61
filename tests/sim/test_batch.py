"""Batch simulation: the compiled controller equals Controller.step; trials explain themselves."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bowden import contracts as c
from bowden.control import ControllerLimits, build_controller
from bowden.model import CompensationLine, CompensationModel
from bowden.model.transmission import slopes_from_friction
from bowden.sim import ProtocolSettings, generate_cohort, simulate_cohort, simulate_trial
from bowden.sim import _batch_kernel as bk
from bowden.sim.parameters import SheathParameters
from bowden.sim.results import TRUE_TENSION, phase_masks, rmse

# The lines of the default simulated suit (its quasi-static slopes; intercepts near the bench's).
_RAISING_SLOPE, _LOWERING_SLOPE = slopes_from_friction(SheathParameters().kinetic_coefficient, 0.035)
MODEL = CompensationModel(
    raising=CompensationLine(intercept_nm=0.11, slope_m=_RAISING_SLOPE),
    lowering=CompensationLine(intercept_nm=-0.11, slope_m=_LOWERING_SLOPE),
)
SHORT = ProtocolSettings(repetitions=2, lead_in_s=0.3, tail_s=0.1)


@pytest.mark.parametrize("support", [0.25, 0.5, "pretension", 1.0])
def test_compiled_controller_equals_controller_step(support: float | str) -> None:
    subject = generate_cohort(0)[3].subject
    limits = ControllerLimits(max_torque_nm=2.0, max_tension_n=60.0, max_torque_rate_nm_s=50.0)
    controller = build_controller(model=MODEL, support=support, subject=subject, limits=limits)  # type: ignore[arg-type]
    vector = bk.controller_vector(controller)
    state = bk.controller_state(controller)  # before its first step: the initial state
    out = np.zeros(5)
    rng = np.random.default_rng(11)
    t = 0.0
    for i in range(3000):
        t += 0.002 if i % 97 else 0.5  # occasional stalls exercise the nominal-period rule
        elevation = rng.uniform(-0.7, 2.8)  # beyond both limits now and then
        velocity = rng.normal(0.0, 3.0) if i % 53 else 25.0
        motor_velocity = math.nan if i % 3 else rng.normal(0.0, 30.0)
        motor_torque = math.inf if i == 1234 else (math.nan if i % 2 else rng.normal(1.0, 1.0))
        if i == 777:
            elevation = math.nan
        expected = controller.step(t, elevation, velocity, motor_velocity, motor_torque)
        bk.controller_step(vector, state, t, elevation, velocity, motor_velocity, motor_torque, out)
        assert out[0] == pytest.approx(expected.torque_nm, abs=1e-12, rel=1e-12)
        if math.isnan(expected.tension_n):
            assert math.isnan(out[1]) and math.isnan(out[2])
        else:
            assert out[1] == pytest.approx(expected.tension_n, abs=1e-12, rel=1e-12)
            assert out[2] == pytest.approx(expected.moment_arm_m, abs=1e-12, rel=1e-12)
        assert int(out[3]) == int(expected.faults)
        assert int(out[4]) == int(expected.limits)


def test_trial_is_reproducible_and_explains_itself() -> None:
    participant = generate_cohort(0)[0]
    trial = simulate_trial(participant, c.CONDITION_SUPPORT_50, "V3", model=MODEL, settings=SHORT, seed=5)
    again = simulate_trial(participant, c.CONDITION_SUPPORT_50, "V3", model=MODEL, settings=SHORT, seed=5)
    frame = trial.to_pandas()
    assert frame.equals(again.to_pandas())
    assert list(frame.columns[: len(c.TRIAL_COLUMNS)]) == list(c.TRIAL_COLUMNS)
    assert np.allclose(np.diff(trial.time_s), 0.002)
    assert "P01" in repr(trial) and "support_50" in repr(trial)
    assert not np.any(np.isnan(trial[c.TRIAL_DESIRED_TENSION]))
    assert np.all(trial[TRUE_TENSION] >= 0.0)
    assert frame[c.TRIAL_FAULT].eq(0).all()
    assert frame[c.TRIAL_STATE].eq(c.LOOP_STATE_RUNNING).all()  # what the runtime loop records when assisting
    masks = phase_masks(trial)
    assert masks["raising"].sum() == pytest.approx(masks["lowering"].sum(), rel=0.01)
    # The reference shown is the paper's minimum-jerk cycle.
    assert trial[c.TRIAL_REFERENCE_ELEVATION].max() == pytest.approx(math.radians(100.0), abs=1e-4)
    # Without a suit nothing of the suit is recorded.
    bare = simulate_trial(participant, c.CONDITION_NO_SUIT, "V3", model=MODEL, settings=SHORT, seed=5)
    assert np.all(np.isnan(bare[c.TRIAL_DESIRED_TENSION]))
    emg = bare.emg()
    assert list(emg.columns) == ["time_s", *c.MUSCLES]
    assert np.diff(emg["time_s"].to_numpy()[:3]) == pytest.approx([0.0005, 0.0005])


def test_tension_error_grows_with_support_and_lowering_exceeds_raising() -> None:
    participant = generate_cohort(0)[1]
    errors = {}
    for condition in (c.CONDITION_PRETENSION, c.CONDITION_SUPPORT_50):
        trial = simulate_trial(participant, condition, "V2", model=MODEL, settings=SHORT, seed=1)
        masks = phase_masks(trial)
        errors[condition] = {
            phase: rmse(trial[TRUE_TENSION][m], trial[c.TRIAL_DESIRED_TENSION][m])
            for phase, m in masks.items()
        }
    assert errors[c.CONDITION_SUPPORT_50]["entire"] > errors[c.CONDITION_PRETENSION]["entire"]
    assert errors[c.CONDITION_SUPPORT_50]["lowering"] > errors[c.CONDITION_SUPPORT_50]["raising"]


def test_cohort_result_with_questionnaires() -> None:
    cohort = generate_cohort(1, n_participants=2, n_female=1)
    settings = ProtocolSettings(repetitions=1, speeds=("V3",), lead_in_s=0.2, tail_s=0.1)
    result = simulate_cohort(cohort, model=MODEL, settings=settings, seed=2)
    assert len(result.trials) == 2 * 4
    for order in result.condition_orders.values():
        assert order[0] == c.CONDITION_NO_SUIT and sorted(order) == sorted(c.CONDITIONS)
    answers = result.questionnaires
    assert set(answers["questionnaire"]) == {"nordic", "borg_rpe", "fatigue"}
    nordic = answers[answers["questionnaire"] == "nordic"]["score"]
    assert nordic.between(1, 7).all()
    rpe = answers[answers["questionnaire"] == "borg_rpe"]["score"]
    assert rpe.between(6, 20).all()
    frame = result.to_pandas()
    assert {"participant_id", "condition", "speed"} <= set(frame.columns)
    assert result.trial("P01", c.CONDITION_PRETENSION, "V3").condition == c.CONDITION_PRETENSION
