"""The bench's mannequin motor as a plant for an :class:`~bowden.sim.peers.AK60Peer`.

On the mannequin bench a second AK-series motor drives the arm's shoulder joint in torque control and
loads the cable (the paper's "Data acquisition"). :class:`MannequinJoint` gives the peer
what it asks of a plant — ``command_motor`` and ``command_motor_mit`` returning a
:class:`~bowden.hardware.protocols.MotorState` — with the joint's angle, velocity and load: its
torque is the load on the arm (> 0 pulls the arm down, against the cable), its position minus
the elevation (the motor's sense: a positive torque turns it positive). A limp motor (out of
motor mode) loads nothing.
"""

from __future__ import annotations

import math
from typing import Any

from bowden.errors import ParameterError
from bowden.hardware.protocols import MotorState
from bowden.sim.arm import MannequinArm
from bowden.sim.peers.wall_time import WallTimePlant

_TEMPERATURE_C = 30.0


class MannequinJoint:
    """The mannequin's joint motor acting on ``arm`` (the :class:`MannequinArm` of the plant's suit).

    Parameters
    ----------
    plant
        The shared simulated suit, built with ``arm``.
    arm
        The mannequin arm whose load torque this motor sets.
    torque_limit_nm
        The motor's peak torque: commands beyond it are clamped, as the real driver's current limit does.
    """

    def __init__(self, plant: WallTimePlant, arm: MannequinArm, *, torque_limit_nm: float = 18.0) -> None:
        if not (math.isfinite(torque_limit_nm) and torque_limit_nm > 0.0):
            raise ParameterError(f"MannequinJoint.torque_limit_nm must be positive, got {torque_limit_nm!r}")
        self._plant = plant
        self._arm = arm
        self.torque_limit_nm = torque_limit_nm

    def enable_motor(self) -> MotorState:
        """Powered, loading nothing yet."""
        return self.command_motor(0.0)

    def command_motor(self, torque_nm: float) -> MotorState:
        """Load the arm with ``torque_nm`` from now on; the joint's state now."""
        torque = min(max(float(torque_nm), -self.torque_limit_nm), self.torque_limit_nm)

        def apply(suit: Any) -> MotorState:
            self._arm.load_torque_nm = torque
            return self._state(suit, torque)

        return self._plant.call(apply)

    def command_motor_mit(self, position_rad: float, velocity_rad_s: float, kp: float, kd: float,
                          torque_nm: float) -> MotorState:
        """An MIT-mode command in the motor's sense (position: minus the elevation), evaluated at every
        plant step from now on, as the motor's own loop does (the bench's impedance mode: its latency
        and study-like segments); the joint's state now, with the torque the law gives now."""
        limit = self.torque_limit_nm

        def apply(suit: Any) -> MotorState:
            self._arm.hold_impedance(-position_rad, -velocity_rad_s, kp, kd, torque_nm, limit)
            state = suit.true_state()
            torque = (torque_nm + kp * (position_rad + float(state.elevation_rad))
                      + kd * (velocity_rad_s + float(state.elevation_velocity_rad_s)))
            return self._state(suit, min(max(torque, -limit), limit))

        return self._plant.call(apply)

    def _state(self, suit: Any, torque_nm: float) -> MotorState:
        state = suit.true_state()
        # The motor's own sense: a positive torque lowers the arm, so a positive rotation does too (an
        # AK motor's position, velocity and torque share one sign); the elevation is minus the angle.
        return MotorState(time_s=float(state.time_s), position_rad=-float(state.elevation_rad),
                          velocity_rad_s=-float(state.elevation_velocity_rad_s), torque_nm=torque_nm,
                          temperature_c=_TEMPERATURE_C, error_code=0)
