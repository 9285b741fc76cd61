"""Watchdog thresholds, the loop's states, and the safe-state ramp.

Every watchdog moves the suit to the same safe state: the motor torque ramps linearly from its last
command to zero over ``ramp_down_s`` (≤ 100 ms, so the arm is not dropped by a step), then motor mode
is exited (limp motor; a zero-torque command alone is not exactly zero on the wire, see
:mod:`bowden.hardware.ak60_codec`). The reason is kept in the run report, logged once, and recorded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

from bowden.contracts import LOOP_STATE_RAMPING_DOWN, LOOP_STATE_RUNNING, LOOP_STATE_SAFE
from bowden.errors import ParameterError

MAX_RAMP_DOWN_S = 0.1


class LoopState(IntEnum):
    """The loop's state, recorded every cycle in the ``controller_state`` column (codes: contracts)."""

    RUNNING = LOOP_STATE_RUNNING  # assistance: the controller's torque goes to the motor
    RAMPING_DOWN = LOOP_STATE_RAMPING_DOWN  # a watchdog or a stop request fired: torque ramps to zero
    SAFE = LOOP_STATE_SAFE  # torque zero and motor mode exited


FAULT_POLICIES = ("stop", "continue")


@dataclass(frozen=True, kw_only=True)
class SafetyConfig:
    """Watchdog thresholds (s, °C, N) and what to do when an evaluation device fails.

    The defaults put every fault at zero torque within 80 ms of its cause: detection (IMU 40 ms,
    motor 30 ms, load cell 20 ms of failed reads) plus the 30 ms ramp plus a cycle.

    Parameters
    ----------
    imu_max_age_s
        An elevation sample older than this, at the moment the loop could read it, stops the suit.
    motor_max_silence_s, motor_min_unanswered
        The motor counts as silent when at least ``motor_min_unanswered`` commands were sent since
        its last valid reply *and* the oldest of them went out ``motor_max_silence_s`` ago. Judged on
        commands actually sent, so a stall of the host (no commands sent) never reads as a dead motor.
    max_transmit_failures
        Consecutive failed command transmissions (CAN) that stop the suit.
    host_stall_max_s
        The loop itself not scheduled for longer than this (beyond its period) stops the suit with
        its own reason; shorter stalls are tolerated (the motor holds its last command), counted,
        recorded as events and reported.
    max_temperature_c
        Motor temperature above this stops the suit (the AK60-6's driver warns near 80 °C; the
        temperature byte's scale is unverified on V1.1, so set it from your motor's behaviour).
    max_tension_n
        A load-cell reading above this stops the suit (only when a load cell is connected).
    load_cell_max_age_s
        With a load cell connected, its reader reporting the sensor lost (failed reads in a row:
        the device, detected within a few tens of ms) or, as a backstop for a reader that hangs, no
        new reading for this long is a lost load cell. Long, because the reader is a thread of this
        host: a busy machine may not schedule it for tens of ms, which is not a lost sensor.
    on_load_cell_lost
        ``"stop"`` (default: the tension limit is a safety limit and cannot be watched any more) or
        ``"continue"``: assistance goes on in an explicit degraded state, flagged in every recorded
        row, logged, recorded as an event and reported.
    on_recorder_failure
        ``"stop"`` (default) or ``"continue"`` without recording (rows are counted as dropped).
    ramp_down_s
        Duration of the torque ramp to zero, ≤ 0.1 s.
    imu_startup_timeout_s
        How long the loop waits for a first elevation sample before refusing to start.
    """

    imu_max_age_s: float = 0.04
    motor_max_silence_s: float = 0.03
    motor_min_unanswered: int = 5
    max_transmit_failures: int = 3
    host_stall_max_s: float = 0.1
    max_temperature_c: float = 80.0
    max_tension_n: float = 200.0
    load_cell_max_age_s: float = 0.25
    on_load_cell_lost: str = "stop"
    on_recorder_failure: str = "stop"
    ramp_down_s: float = 0.03
    imu_startup_timeout_s: float = 2.0

    def __post_init__(self) -> None:
        for name in ("imu_max_age_s", "motor_max_silence_s", "host_stall_max_s", "max_temperature_c",
                     "max_tension_n", "load_cell_max_age_s", "ramp_down_s", "imu_startup_timeout_s"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise ParameterError(f"SafetyConfig.{name} must be a finite number, got {value!r}")
            if value <= 0.0:
                raise ParameterError(f"SafetyConfig.{name} must be positive, got {value!r}")
        for name in ("motor_min_unanswered", "max_transmit_failures"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ParameterError(f"SafetyConfig.{name} must be a whole number ≥ 1, got {value!r}")
        for name in ("on_load_cell_lost", "on_recorder_failure"):
            if getattr(self, name) not in FAULT_POLICIES:
                raise ParameterError(
                    f"SafetyConfig.{name} must be one of {FAULT_POLICIES}, got {getattr(self, name)!r}"
                )
        if self.ramp_down_s > MAX_RAMP_DOWN_S:
            raise ParameterError(
                f"SafetyConfig.ramp_down_s must be at most {MAX_RAMP_DOWN_S} s, got {self.ramp_down_s}"
            )


def ramp_torque_nm(start_torque_nm: float, elapsed_s: float, ramp_down_s: float) -> float:
    """Torque of the safe-state ramp ``elapsed_s`` after it began (linear, exactly 0 at the end).

    The end is taken 1 ns early so that a cycle landing on it, up to rounding, already commands zero.
    """
    if elapsed_s >= ramp_down_s - 1e-9:
        return 0.0
    if elapsed_s <= 0.0:
        return start_torque_nm
    return start_torque_nm * (1.0 - elapsed_s / ramp_down_s)
