"""The simulated mannequin motor speaks in an AK motor's own sense: its position, velocity and torque
share one sign, so an MIT-mode target it is driven towards is where its torque takes the arm."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from bowden.sim.arm import MannequinArm
from bowden.sim.peers.mannequin import MannequinJoint


class _Plant:  # what MannequinJoint asks of the wall-time plant: call(fn) on the suit
    def __init__(self, elevation_rad: float, velocity_rad_s: float) -> None:
        self.state = SimpleNamespace(time_s=0.0, elevation_rad=elevation_rad,
                                     elevation_velocity_rad_s=velocity_rad_s)

    def call(self, action):
        return action(SimpleNamespace(true_state=lambda: self.state))


def test_the_joint_reports_minus_the_elevation_as_a_positive_torque_lowers_the_arm():
    joint = MannequinJoint(_Plant(1.0, 0.5), MannequinArm())  # type: ignore[arg-type]
    state = joint.command_motor(0.0)
    # A positive torque lowers the arm: the motor's positive rotation is downwards.
    assert state.position_rad == pytest.approx(-1.0) and state.velocity_rad_s == pytest.approx(-0.5)


def test_an_mit_target_below_the_arm_pulls_it_down_and_one_above_lifts_it():
    arm = MannequinArm()
    joint = MannequinJoint(_Plant(1.0, 0.0), arm)  # type: ignore[arg-type]
    # Elevation 0.9 rad is motor position -0.9: above the arm's -1.0 in the motor's sense.
    joint.command_motor_mit(-0.9, 0.0, 25.0, 0.0, 0.0)
    assert arm.load_torque_nm == pytest.approx(2.5)  # > 0 pulls the arm down, towards 0.9 rad
    joint.command_motor_mit(-math.radians(70.0), 0.0, 25.0, 0.0, 0.0)
    assert arm.load_torque_nm < 0.0  # lifts it towards 70°
