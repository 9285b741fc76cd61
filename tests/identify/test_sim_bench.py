"""End to end on the simulated mannequin bench (bowden.sim): identified lines against the plant's physics.

The plant's quasi-static motor torque (reported by the driver) in steady sliding is
τ = [R·T_out·(1 + s·k)/(1 − s·k) + s·(τ_c + b·|ω|)] / c, with R the spool radius, k the sheath's
kinetic μ·sin(φ/2), τ_c and b the motor's Coulomb and viscous friction and c the torque-constant
ratio (delivered over reported torque). So the slopes must be R(1+k)/(1−k)/c raising and
R(1−k)/(1+k)/c lowering (the friction terms only move the intercepts).
"""

from __future__ import annotations

import dataclasses

import pytest

from bowden.identify import TransmissionIdentifier
from bowden.model.transmission import slopes_from_friction
from bowden.sim import batch, bench, parameters, participants, results

# A reduced protocol (every speed decade, all load extremes, one repetition) keeps the test fast.
PROTOCOL = {"spool_speeds_rad_s": (0.5, 2.0, 6.0), "loads_nm": (0.5, 2.0, 4.0), "repetitions": 1}


def quasi_static_slopes(suit: object) -> tuple[float, float]:
    motor, sheath = suit.motor, suit.sheath  # type: ignore[attr-defined]
    raising, lowering = slopes_from_friction(sheath.kinetic_coefficient, motor.spool_radius_m)
    return raising / motor.torque_constant_ratio, lowering / motor.torque_constant_ratio


def test_identification_of_the_simulated_bench_matches_the_plant() -> None:
    suit = parameters.SuitParameters()
    frame = bench.run_bench(suit, bench.BenchProtocol(**PROTOCOL), seed=3)
    identifier = TransmissionIdentifier(pulley_radius_m=suit.motor.spool_radius_m).fit(frame)
    raising, lowering = quasi_static_slopes(suit)
    model = identifier.model_
    assert model.raising.slope_m == pytest.approx(raising, rel=0.03)
    assert model.lowering.slope_m == pytest.approx(lowering, rel=0.03)
    for fit in (model.raising_fit, model.lowering_fit):
        assert fit is not None
        assert fit.r_squared_robust >= 0.99 and fit.r_squared_ols >= 0.99
    assert identifier.summary_.k == pytest.approx(suit.sheath.kinetic_coefficient, rel=0.05)
    assert identifier.summary_.consistent_with_one_k


def test_torque_constant_error_on_the_simulated_bench_is_flagged() -> None:
    # A driver that under-reports torque by 15 %: both slopes shrink by 1/1.15, k survives, and the
    # single-bend check sees the geometric mean of the slopes 13 % below the spool radius.
    default = parameters.SuitParameters()
    motor = parameters.MotorParameters(torque_constant_ratio=1.15)
    suit = parameters.SuitParameters(motor=motor, sheath=default.sheath)
    frame = bench.run_bench(suit, bench.BenchProtocol(**PROTOCOL), seed=4)
    identifier = TransmissionIdentifier().fit(frame)
    raising, lowering = quasi_static_slopes(suit)
    assert identifier.model_.raising.slope_m == pytest.approx(raising, rel=0.03)
    assert identifier.model_.lowering.slope_m == pytest.approx(lowering, rel=0.03)
    assert identifier.summary_.radius_deviation == pytest.approx(1.0 / 1.15 - 1.0, abs=0.02)
    assert not identifier.summary_.consistent_with_one_k


def test_identified_model_controls_the_simulated_suit() -> None:
    # Closed loop: the controller with the identified model on the simulated suit, 50 % support.
    # It must track far better than ignoring friction (k = 0, the naive R·T law) and better than the
    # right k without the motor-friction intercepts, and stay under the paper's worst tension RMSE
    # (9.07 N, Table of tension RMSE; the paper's 50 % support values are 6.1–8.2 N).
    from bowden.contracts import TRIAL_DESIRED_TENSION
    from bowden.model import CompensationModel

    suit = parameters.SuitParameters()
    frame = bench.run_bench(suit, bench.BenchProtocol(**PROTOCOL), seed=3)
    identified = TransmissionIdentifier().fit(frame).model_
    no_friction = CompensationModel.from_friction(k=0.0)
    slopes_only = CompensationModel.from_friction(k=suit.sheath.kinetic_coefficient)
    # A steady participant (little motor noise, no wandering lag): the model's effect, not the noise's.
    steady = {"motor_noise_nm": 0.1, "lag_wander_sd": 0.0}
    participant = dataclasses.replace(participants.generate_cohort(0)[0], **steady)
    settings = batch.ProtocolSettings(repetitions=3)

    def tension_rmse_n(model: CompensationModel, speed: str) -> float:
        trial = batch.simulate_trial(participant, "support_50", speed, model=model, settings=settings, seed=5)
        inside = results.phase_masks(trial)["entire"]
        return float(results.rmse(trial[results.TRUE_TENSION][inside], trial[TRIAL_DESIRED_TENSION][inside]))

    for speed in ("V1", "V3"):
        achieved = tension_rmse_n(identified, speed)
        assert achieved < 9.07
        assert achieved < 0.5 * tension_rmse_n(no_friction, speed)
        assert achieved < tension_rmse_n(slopes_only, speed)
