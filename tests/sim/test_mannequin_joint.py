"""The simulated mannequin motor speaks in an AK motor's own sense: its position, velocity and torque
share one sign, so an MIT-mode target it is driven towards is where its torque takes the arm."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from bowden.sim import _kernels as k
from bowden.sim.arm import MannequinArm
from bowden.sim.peers import WallTimePlant
from bowden.sim.peers.mannequin import MannequinJoint
from bowden.sim.suit import SimulatedSuit


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
    state = joint.command_motor_mit(-0.9, 0.0, 25.0, 0.0, 0.0)
    assert state.torque_nm == pytest.approx(2.5)  # > 0 pulls the arm down, towards 0.9 rad
    assert arm.mode == k.ARM_IMPEDANCE and arm.human()[k.A_ELEVATION] == pytest.approx(0.9)
    state = joint.command_motor_mit(-math.radians(70.0), 0.0, 25.0, 0.0, 0.0)
    assert state.torque_nm < 0.0  # lifts it towards 70°
    joint.command_motor(1.0)  # a torque command ends MIT mode
    assert arm.mode == k.ARM_TORQUE and arm.load_torque_nm == 1.0


class _Clock:
    def __init__(self) -> None:
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s


def test_an_mit_command_holds_the_arm_at_its_target_while_the_host_sends_nothing():
    # The motor's own loop evaluates the law at every step. Before, the torque of the moment of the
    # command was held until the next one: a host that stalled 0.3 s after one command of a stiff
    # position loop let the arm run far past the target.
    clock = _Clock()
    arm = MannequinArm(initial_elevation_rad=math.radians(40.0))
    plant = WallTimePlant(SimulatedSuit(arm=arm), time_source=clock)
    joint = MannequinJoint(plant, arm)
    plant.start()
    target = math.radians(60.0)
    joint.command_motor_mit(-target, 0.0, 100.0, 2.5, 0.0)
    clock.now_s = 0.3
    elevation = plant.call(lambda suit: suit.true_state().elevation_rad)
    assert abs(elevation - target) < math.radians(5.0), math.degrees(elevation)
    clock.now_s = 1.5
    state = plant.call(lambda suit: suit.true_state())
    assert abs(state.elevation_rad - target) < math.radians(3.0), math.degrees(state.elevation_rad)
    assert abs(state.elevation_velocity_rad_s) < 0.1
