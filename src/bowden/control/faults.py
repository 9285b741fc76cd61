"""Fault and limit flags of a control cycle, as recorded in trial recordings (``fault_flags``).

The controller raises the input faults; the runtime loop's watchdogs raise the others. Bits are part of
the recording contract: never renumber, only add.
"""

from __future__ import annotations

from enum import IntFlag


class Fault(IntFlag):
    """Why a cycle commanded the safe torque (zero) instead of assistance."""

    NONE = 0
    NONFINITE_INPUT = 1 << 0  # NaN or infinite time, elevation, velocity or motor reading
    ELEVATION_OUT_OF_RANGE = 1 << 1
    ELEVATION_VELOCITY_OUT_OF_RANGE = 1 << 2
    MOTOR_OVERSPEED = 1 << 3
    # Raised by the runtime loop's watchdogs.
    IMU_STALE = 1 << 8
    MOTOR_NO_REPLY = 1 << 9
    MOTOR_ERROR = 1 << 10
    MOTOR_OVER_TEMPERATURE = 1 << 11
    TENSION_LIMIT = 1 << 12
    STOP_REQUESTED = 1 << 13
    TRANSMIT_FAILED = 1 << 14
    HOST_STALL = 1 << 15  # the loop itself was not scheduled for longer than the tolerated bound
    LOAD_CELL_LOST = 1 << 16  # the load cell stopped delivering: the tension limit cannot be watched
    RECORDER_FAILED = 1 << 17  # the trial recording cannot keep up or cannot write
    SLACK_NOT_TAKEN_UP = 1 << 18  # no tension within the slack take-up's time: a cable not attached?


class Limit(IntFlag):
    """Which limit shaped a cycle's command (not a fault: assistance continues)."""

    NONE = 0
    TENSION = 1 << 0  # desired tension clamped to the maximum
    TORQUE = 1 << 1  # torque clamped to the motor's range
    TORQUE_RATE = 1 << 2  # torque change clamped by the rate limit
