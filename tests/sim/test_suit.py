"""SimulatedSuit behind the hardware protocols: clock, motor, IMU and load cell."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bowden.errors import HardwareError, ParameterError
from bowden.hardware.protocols import Clock, ElevationSensor, Motor, TensionSensor
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.sim import (
    ExpectedAssistance,
    ImuParameters,
    LoadCellParameters,
    MannequinArm,
    MotorParameters,
    ParticipantArm,
    PrescribedArm,
    SimulatedSuit,
    SuitParameters,
    generate_cohort,
)


def test_faces_implement_the_hardware_protocols() -> None:
    suit = SimulatedSuit()
    assert isinstance(suit.motor, Motor)
    assert isinstance(suit.elevation_sensor, ElevationSensor)
    assert isinstance(suit.tension_sensor, TensionSensor)
    assert isinstance(suit.clock, Clock)


def test_clock_advances_the_physics_and_never_goes_back() -> None:
    suit = SimulatedSuit()
    assert suit.clock.now() == 0.0
    suit.clock.sleep_until(0.1)
    assert suit.clock.now() == pytest.approx(0.1)
    assert suit.true_state().time_s == pytest.approx(0.1, abs=suit.parameters.substep_s)
    suit.advance_to(0.05)
    assert suit.clock.now() == pytest.approx(0.1)
    with pytest.raises(ParameterError, match="finite"):
        suit.advance_to(math.nan)


def test_motor_needs_enabling_and_reports_the_drivers_torque_estimate() -> None:
    ratio = 0.85
    suit = SimulatedSuit(SuitParameters(motor=MotorParameters(torque_constant_ratio=ratio)))
    with pytest.raises(HardwareError, match="enable"):
        suit.motor.command_torque(0.3)
    suit.motor.enable()
    suit.motor.command_torque(0.3)
    suit.clock.sleep_until(0.05)  # 50 current-loop time constants
    reply = suit.motor.command_torque(0.3)
    delivered = suit.true_state().motor_torque_nm
    assert delivered == pytest.approx(0.3 * ratio, rel=1e-9)
    assert reply.torque_nm == pytest.approx(0.3, rel=1e-9)
    with pytest.raises(HardwareError, match="finite"):
        suit.motor.command_torque(math.inf)
    with suit.motor:
        pass
    assert not suit.motor.enabled


def test_set_zero_and_impedance_hold_position() -> None:
    suit = SimulatedSuit(initial_tension_n=10.0)
    suit.motor.enable()
    suit.motor.set_zero()
    assert suit.motor.state().position_rad == 0.0
    suit.motor.command_impedance(0.5, 0.0, 20.0, 0.5, 0.0)
    suit.clock.sleep_until(1.0)
    state = suit.motor.state()
    # kp·(0.5 − p) balances the cable: p stops short of 0.5 by R·T/kp.
    tension = suit.true_state().sheath_entry_tension_n
    assert state.position_rad == pytest.approx(0.5 - 0.035 * tension / 20.0, abs=0.01)


def test_imu_noise_and_bias_statistics() -> None:
    imu = ImuParameters(
        sample_rate_hz=500.0, elevation_noise_rad=0.01, elevation_bias_rad=0.02,
        velocity_noise_rad_s=0.03, velocity_bias_rad_s=-0.01, latency_s=0.0,
    )
    th = math.radians(40.0)
    suit = SimulatedSuit(SuitParameters(imu=imu), PrescribedArm.hold(th), seed=3)
    errors, velocities = [], []
    for i in range(1, 3001):
        suit.clock.sleep_until(i * 0.002)
        sample = suit.elevation_sensor.read()
        assert sample is not None
        errors.append(sample.elevation_rad - th)
        velocities.append(sample.elevation_velocity_rad_s)
    assert np.mean(errors) == pytest.approx(0.02, abs=0.001)
    assert np.std(errors) == pytest.approx(0.01, rel=0.08)
    assert np.mean(velocities) == pytest.approx(-0.01, abs=0.003)
    assert np.std(velocities) == pytest.approx(0.03, rel=0.08)


def test_imu_latency_delays_the_elevation() -> None:
    imu = ImuParameters(elevation_noise_rad=0.0, elevation_bias_rad=0.0, velocity_noise_rad_s=0.0,
                        velocity_bias_rad_s=0.0, latency_s=0.05, sample_rate_hz=400.0)
    speed = 0.5
    arm = PrescribedArm(
        elevation_rad=lambda t: 0.5 + speed * t, elevation_velocity_rad_s=lambda t: speed + 0 * t
    )
    suit = SimulatedSuit(SuitParameters(imu=imu), arm)
    suit.clock.sleep_until(1.0)
    sample = suit.elevation_sensor.read()
    assert sample is not None
    assert sample.elevation_rad == pytest.approx(0.5 + speed * (sample.time_s - 0.05), abs=1e-3)


def test_load_cell_reads_the_anchor_tension_with_noise() -> None:
    cell = LoadCellParameters(noise_n=0.5, offset_n=1.0)
    suit = SimulatedSuit(SuitParameters(load_cell=cell), initial_tension_n=12.0, seed=1)
    suit.motor.enable()
    suit.motor.command_torque(0.035 * 12.0)
    readings = []
    for i in range(1, 2001):
        suit.clock.sleep_until(i * 0.002)
        sample = suit.tension_sensor.read()
        assert sample is not None
        readings.append(sample.tension_n - suit.true_state().anchor_tension_n)
    assert np.mean(readings) == pytest.approx(1.0, abs=0.05)
    assert np.std(readings) == pytest.approx(0.5, rel=0.1)


def test_mannequin_arm_falls_when_the_motor_is_limp() -> None:
    arm = MannequinArm(load_torque_nm=1.0, initial_elevation_rad=math.radians(80.0))
    suit = SimulatedSuit(arm=arm, initial_tension_n=10.0)
    suit.clock.sleep_until(1.0)
    assert suit.true_state().elevation_rad < math.radians(40.0)


def test_participant_tracks_the_reference_with_the_controller_in_the_loop() -> None:
    from bowden.control import build_controller
    from bowden.model import CompensationModel

    participant = generate_cohort(2)[0]
    cycle = MinimumJerkCycle(peak_speed_rad_s=math.radians(120.0))
    expected = ExpectedAssistance.for_condition(0.5, participant.subject)
    suit = SimulatedSuit(
        arm=ParticipantArm(participant, cycle, cycles=2, start_s=0.5, expected=expected),
        seed=4, initial_tension_n=10.0,
    )
    controller = build_controller(model=CompensationModel.from_friction(k=0.14), support=0.5,
                                  subject=participant.subject)
    suit.motor.enable()
    t, errors, tension_errors = 0.0, [], []
    while t < 0.5 + 2 * cycle.period_s:
        sample = suit.elevation_sensor.read()
        th, thd = (sample.elevation_rad, sample.elevation_velocity_rad_s) if sample else (0.35, 0.0)
        command = controller.step(t, th, thd)
        suit.motor.command_torque(command.torque_nm)
        truth = suit.true_state()
        if t > 1.0:
            errors.append(truth.elevation_rad - float(cycle.elevation_rad(t - 0.5)))
            tension_errors.append(truth.anchor_tension_n - command.tension_n)
        t += 0.002
        suit.clock.sleep_until(t)
    rmse_deg = math.degrees(math.sqrt(np.mean(np.square(errors))))
    assert 2.0 < rmse_deg < 20.0  # tracks, with a human's lag
    assert 1.0 < math.sqrt(np.mean(np.square(tension_errors))) < 15.0
