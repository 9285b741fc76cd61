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


@dataclass(frozen=True, kw_only=True)
class SafetyConfig:
    """Watchdog thresholds (s, °C, N).

    Parameters
    ----------
    imu_max_age_s
        Elevation samples older than this stop the suit (issue 5: 50 ms).
    motor_max_silence_s
        No valid motor reply for this long stops the suit.
    max_temperature_c
        Motor temperature above this stops the suit (the AK60-6's driver warns near 80 °C; the
        temperature byte's scale is unverified on V1.1, so set it from your motor's behaviour).
    max_tension_n
        A load-cell reading above this stops the suit (only when a load cell is connected).
    ramp_down_s
        Duration of the torque ramp to zero, ≤ 0.1 s.
    imu_startup_timeout_s
        How long the loop waits for a first elevation sample before refusing to start.
    """

    imu_max_age_s: float = 0.05
    motor_max_silence_s: float = 0.02
    max_temperature_c: float = 80.0
    max_tension_n: float = 200.0
    ramp_down_s: float = 0.05
    imu_startup_timeout_s: float = 2.0

    def __post_init__(self) -> None:
        for name in ("imu_max_age_s", "motor_max_silence_s", "max_temperature_c", "max_tension_n",
                     "ramp_down_s", "imu_startup_timeout_s"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise ParameterError(f"SafetyConfig.{name} must be a finite number, got {value!r}")
            if value <= 0.0:
                raise ParameterError(f"SafetyConfig.{name} must be positive, got {value!r}")
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
