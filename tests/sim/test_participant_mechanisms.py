"""The virtual participants' mechanisms (issue 18, item 1), each on its own.

Hand-derived activations for corrections and co-contraction; the compiled participant's learning,
co-contraction and lag against runs with the mechanism switched off; practice and session order.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest

from bowden import contracts as c
from bowden.errors import ParameterError
from bowden.model import CompensationModel
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.sim import _kernels as k
from bowden.sim import muscles
from bowden.sim.batch import ProtocolSettings, session_trial, simulate_trial
from bowden.sim.participants import generate_cohort, human_vector
from bowden.sim.results import COCONTRACTION, CORRECTION_TORQUE, TRUE_ELEVATION

MAX_TORQUE = 40.0
N = 2000  # 4 s at 500 Hz: the activation dynamics have settled
PD = c.MUSCLES.index("posterior_deltoid")
AD = c.MUSCLES.index("anterior_deltoid")
QUIET = dict(
    motor_noise_nm=0.0, motor_noise_fraction=0.0, lag_wander_sd=0.0, lag_trial_sd=0.0,
    excursion_repetition_sd=0.0,
)


def _settled(**kwargs: np.ndarray) -> np.ndarray:
    th = np.full(N, 0.5)
    act = muscles.muscle_activations(
        kwargs.pop("net"), th, np.zeros(N), sample_rate_hz=500.0, max_torque_nm=MAX_TORQUE, **kwargs
    )
    return act[-1]


def test_a_downward_correction_is_made_by_the_extensors_while_the_flexors_hold_the_arm() -> None:
    net = np.full(N, 3.0)
    planned_only = _settled(net=net)
    # Same net torque, but 1 Nm of it is a downward correction: the planned torque is 4 Nm.
    corrected = _settled(net=net, correction_torque_nm=np.full(N, -1.0))
    # 1 Nm more on each side: the flexors' planned torque and the extensors' correction.
    both_sides = (muscles._AGONIST + muscles._ANTAGONIST) / MAX_TORQUE
    assert corrected[PD] - planned_only[PD] == pytest.approx(both_sides[PD], rel=1e-6)
    assert corrected[AD] - planned_only[AD] == pytest.approx(both_sides[AD], rel=1e-6)
    assert corrected[PD] - planned_only[PD] > 20 * muscles._AGONIST[PD] / MAX_TORQUE
    # Netted (the old model), the extensor would not have moved at all.
    assert np.array_equal(_settled(net=net, correction_torque_nm=np.zeros(N)), planned_only)


def test_cocontraction_activates_both_sides_and_leaves_the_net_torque() -> None:
    net = np.full(N, 2.0)
    base = _settled(net=net)
    stiff = _settled(net=net, cocontraction_nm=np.full(N, 0.8))
    expected = (muscles._AGONIST + muscles._ANTAGONIST) * 0.8 / MAX_TORQUE
    expected[muscles._TRAPEZIUS] *= 0.6 + 0.8 * 0.5 / (0.5 * math.pi)  # its upward-rotation factor
    np.testing.assert_allclose(stiff - base, expected, rtol=1e-6)


def test_a_correction_of_the_wrong_shape_is_refused() -> None:
    with pytest.raises(ParameterError, match="correction_torque_nm"):
        muscles.muscle_activations(
            np.zeros(10), np.zeros(10), np.zeros(10), sample_rate_hz=500.0, max_torque_nm=40.0,
            correction_torque_nm=np.zeros(9),
        )


@pytest.fixture(scope="module")
def participant():
    return dataclasses.replace(generate_cohort(0, n_participants=2)[0], **QUIET)


def _trial(participant, condition="no_suit", **fields):
    model = CompensationModel.from_friction(k=0.1)
    settings = ProtocolSettings(repetitions=8, speeds=("V2",))
    who = dataclasses.replace(participant, **fields)
    return simulate_trial(who, condition, "V2", model=model, settings=settings, seed=3)


def _repetition_rmse(trial) -> np.ndarray:
    rep = trial.repetition_index()
    error = trial[TRUE_ELEVATION] - trial[c.TRIAL_REFERENCE_ELEVATION]
    return np.array([math.sqrt(np.mean(error[rep == r] ** 2)) for r in range(trial.repetitions)])


def test_learning_moves_what_the_feedback_keeps_supplying_into_the_plan(participant) -> None:
    # A participant that over-estimates its arm's weight by 15 %: its feedback has to pull the arm
    # down on every cycle. Learning takes that over, so the later corrections shrink...
    # A participant that over-estimates its arm's weight by 15 % holds it too high, and its feedback
    # has to pull it down on every cycle; learning takes that over, so the arm's bias shrinks.
    wrong = dict(internal_model_error=1.15, cocontraction_gain=0.0)
    learning = _trial(participant, learning_cycles=2.0, **wrong)
    fixed = _trial(participant, learning_cycles=0.0, **wrong)
    right = _trial(participant, learning_cycles=0.0, cocontraction_gain=0.0, internal_model_error=1.0)

    def bias(trial, first: int, last: int) -> float:
        rep = trial.repetition_index()
        inside = (rep >= first) & (rep <= last)
        return float(np.mean((trial[TRUE_ELEVATION] - trial[c.TRIAL_REFERENCE_ELEVATION])[inside]))

    error_bias = bias(fixed, 5, 7) - bias(right, 5, 7)
    assert error_bias > math.radians(0.5)  # the wrong model holds the arm higher
    assert bias(fixed, 1, 2) == pytest.approx(bias(fixed, 5, 7), rel=0.02)  # and stays so
    assert bias(learning, 5, 7) - bias(right, 5, 7) < 0.3 * error_bias
    # The learned torque is part of the correction, so the correction does not vanish with learning.
    late = learning.repetition_index() >= 5
    assert np.mean(learning[CORRECTION_TORQUE][late]) < -0.2


def test_cocontraction_builds_with_the_errors_and_vanishes_without_gain(participant) -> None:
    none = _trial(participant, "support_50", cocontraction_gain=0.0)
    assert np.all(none[COCONTRACTION] == 0.0)
    small = _trial(participant, "support_50", internal_model_error=1.0)
    large = _trial(participant, "support_50", internal_model_error=1.15, learning_cycles=0.0)
    assert np.all(small[COCONTRACTION] >= 0.0)
    assert np.mean(large[COCONTRACTION]) > np.mean(small[COCONTRACTION])


def test_the_lag_wanders_between_repetitions_only_when_asked(participant) -> None:
    steady = _repetition_rmse(_trial(participant, learning_cycles=0.0, cocontraction_gain=0.0))[2:]
    wandering = _repetition_rmse(
        _trial(participant, learning_cycles=0.0, cocontraction_gain=0.0, lag_wander_sd=0.3)
    )[2:]
    assert np.std(steady) / np.mean(steady) < 0.01  # a noiseless participant repeats itself
    assert np.std(wandering) / np.mean(wandering) > 0.03


def test_practice_shortens_the_lag_over_the_session(participant) -> None:
    lags = [participant.trial_lag_s(n, 0.0) for n in range(12)]
    assert lags[0] == participant.visuomotor_lag_s
    assert all(b < a for a, b in itertools.pairwise(lags))
    floor = participant.visuomotor_lag_s * (1.0 - participant.practice_lag_reduction)
    assert participant.trial_lag_s(10_000, 0.0) == pytest.approx(floor)
    assert participant.trial_lag_s(0, 1.0) == pytest.approx(
        participant.visuomotor_lag_s * math.exp(participant.lag_trial_sd)
    )
    with pytest.raises(ParameterError, match="session_trial"):
        participant.trial_lag_s(-1, 0.0)


def test_session_trial_counts_the_trials_before() -> None:
    order = ("no_suit", "support_50", "pretension", "support_25")
    assert session_trial(order, "no_suit", c.SPEEDS, "V1") == 0
    assert session_trial(order, "support_50", c.SPEEDS, "V3") == 5
    assert session_trial(order, "support_25", c.SPEEDS, "V2") == 10
    with pytest.raises(ParameterError, match="support_70"):
        session_trial(order, "support_70", c.SPEEDS, "V1")


def test_practice_reaches_the_trial(participant) -> None:
    first = _trial(participant, learning_cycles=0.0)
    model = CompensationModel.from_friction(k=0.1)
    settings = ProtocolSettings(repetitions=8, speeds=("V2",))
    who = dataclasses.replace(participant, learning_cycles=0.0, practice_lag_reduction=0.3)
    practised = simulate_trial(who, "no_suit", "V2", model=model, settings=settings, seed=3, session_trial=11)
    assert np.mean(_repetition_rmse(practised)[1:]) < 0.95 * np.mean(_repetition_rmse(first)[1:])


def test_each_repetition_has_the_excursion_of_its_own_draw(participant) -> None:
    cycle = MinimumJerkCycle(low_rad=0.3, high_rad=1.7, peak_speed_rad_s=2.0)
    draws = np.array([0.0, 1.0, -2.0])
    who = dataclasses.replace(participant, excursion_repetition_sd=0.1)
    h = human_vector(who, cycle, cycles=3, start_s=1.0, expected=None, excursion_draws=draws)
    period = 2.0 * cycle.movement_duration_s
    for repetition, draw in enumerate(draws):
        middle = 1.0 + (repetition + 0.5) * period
        assert k.repetition_excursion(h, middle) == pytest.approx(math.exp(0.1 * draw), rel=1e-12)
    assert k.repetition_excursion(h, 0.0) == 1.0  # before the start: the first repetition's
    assert k.repetition_excursion(h, 1.0 + 10 * period) == pytest.approx(math.exp(-0.2))  # after: the last's
    # Without draws, or without spread, every repetition is alike.
    assert k.repetition_excursion(human_vector(who, cycle, cycles=3, start_s=1.0, expected=None), 2.0) == 1.0
    with pytest.raises(ParameterError, match="one finite draw per repetition"):
        human_vector(who, cycle, cycles=3, start_s=1.0, expected=None, excursion_draws=np.zeros(2))


def test_repetitions_reach_different_peaks_only_when_asked(participant) -> None:
    def excursions(trial) -> np.ndarray:
        rep = trial.repetition_index()
        low = math.radians(c.ELEVATION_LOW_DEG)
        return np.array([trial[TRUE_ELEVATION][rep == r].max() - low for r in range(trial.repetitions)])

    plain = dict(learning_cycles=0.0, cocontraction_gain=0.0)
    steady = excursions(_trial(participant, **plain))[1:]
    varied = excursions(_trial(participant, **plain, excursion_repetition_sd=0.1))[1:]
    assert np.std(steady) / np.mean(steady) < 0.005
    assert np.std(varied) / np.mean(varied) > 0.03
    assert np.mean(varied) == pytest.approx(np.mean(steady), rel=0.1)
