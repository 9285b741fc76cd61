"""One cycle of the bench's fixed-rate loop: wait for its deadline, sense, command both motors, record.
"""

from __future__ import annotations

import math

from bowden.errors import TransmitError
from bowden.runtime.bench_config import BenchFault
from bowden.runtime.bench_sensing import BenchSensing
from bowden.runtime.bench_state import PHASE_HOLD, PHASE_SETTLE, PHASE_STROKE

_HOST_STALL_S = 0.01  # a cycle this late is a stall of the host
# The spool target advances by the clock, but by at most this much time per cycle: after a stall of
# the host the motor held its last target, and a jump of the whole stall would jerk the cable.
_MAX_ADVANCE_S = _HOST_STALL_S


class BenchCycle(BenchSensing):
    """The loop's cycle (the spool target advances by the clock) and the rows it records."""

    def _begin_cycle(self) -> float:
        """Wait for the next cycle's deadline, then read and check the sensors; the clock time now."""
        clock = self.devices.clock
        self._deadline += self.period_s
        clock.sleep_until(self._deadline)
        self._stop_if_requested()  # here, between cycles, no device call is under way
        now = clock.now()
        if now - self._deadline > _HOST_STALL_S:
            # Behind (a stall, or cycles late one after another): no burst of catch-up cycles.
            self._deadline = now
        if now - self._last_cycle_s > self.period_s + _HOST_STALL_S:
            # The host stalled (a stroke's fsync, the scheduler): replies and samples missing across
            # the stall are not the devices' fault. Only a gap between two cycles is a stall: a loop
            # that merely falls behind would otherwise discount every age for good.
            self._stall_end_s = now
        # The target advances with the time that passed, not with the cycles: a loop that falls
        # behind (cycles late, no stall) would otherwise run the stroke slow.
        self._cycle_dt_s = min(max(now - self._last_cycle_s, 0.0), _MAX_ADVANCE_S)
        self._last_cycle_s = now
        self._sense(now)
        self._reference_joint()
        if self._phase in (PHASE_STROKE, PHASE_SETTLE) and self._stroke is not None:
            direction = 1.0 if self._stroke.raising else -1.0
            self._furthest_rad = direction * max(direction * self._furthest_rad,
                                                 direction * self._elevation_rad)
        return now

    def _cycle_once(self, *, velocity_rad_s: float | None = None, kp: float | None = None,
                    kd: float | None = None) -> None:
        now = self._begin_cycle()
        p = self.config.protocol
        velocity = self._velocity_rad_s if velocity_rad_s is None else velocity_rad_s
        self._target_rad += velocity * self._cycle_dt_s
        if abs(velocity) > 0.05:
            self._arrival = 1.0 if velocity > 0.0 else -1.0
        self._load_command_nm = self._load_now(now)
        self._mannequin_command_nm = self._load_command_nm + self._wall_torque_nm()
        try:
            state = self.devices.mannequin.command_torque(self._mannequin_command_nm)
            self._mannequin_state = state or self._mannequin_state
            if kp is not None and kp == 0.0:
                state = self.devices.tdu.command_mit(0.0, velocity, 0.0, kd or 0.0)
            else:
                state = self.devices.tdu.command_mit(self._target_rad, velocity, p.position_gain_nm_rad,
                                                     p.velocity_gain_nms_rad)
            self._tdu_state = state or self._tdu_state
            self._transmit_failures = 0
        except TransmitError as error:
            self._transmit_failed(error)
        if kp is not None and kp == 0.0 and self._tdu_state is not None:
            self._target_rad = self._tdu_state.position_rad  # velocity mode: the target follows
        self._check_motors(now)
        self._record(now, velocity)
        self._cycle += 1

    def _transmit_failed(self, error: TransmitError) -> None:
        self._transmit_failures += 1
        if self._transmit_failures >= self.config.safety.max_transmit_failures:
            raise BenchFault(f"CAN transmit failed {self._transmit_failures} times in a row: "
                             f"{error}") from None

    def _time_s(self, now: float) -> float:
        """The recording's time of the clock time ``now`` (continuing after a resume)."""
        return now - self._origin_s + self._time_offset_s

    def _record_log(self, now: float) -> None:
        """A device-log row of a later segment (no spool target: the TDU runs in torque mode)."""
        tdu, man = self._tdu_state, self._mannequin_state
        nan = math.nan
        self._log_rows.append((
            self._time_s(now), -1, self._phase, nan, nan, tdu.position_rad if tdu else nan,
            nan, man.torque_nm if man else nan, man.position_rad if man else nan,
            man.velocity_rad_s if man else nan,
        ))

    def _record(self, now: float, velocity: float) -> None:
        if self._cycle % self.record_every:
            return
        t = now - self._origin_s + self._time_offset_s
        tdu, man = self._tdu_state, self._mannequin_state
        trial = self._stroke.index if self._stroke is not None else -1
        nan = math.nan
        if self._phase in (PHASE_HOLD, PHASE_STROKE, PHASE_SETTLE) and self._stroke is not None \
                and tdu is not None:
            self._rows.append((t, tdu.torque_nm, tdu.velocity_rad_s, self._tension_n, self._elevation_rad,
                               trial))
        self._log_rows.append((
            t, trial, self._phase, self._target_rad, velocity, tdu.position_rad if tdu else nan,
            self._mannequin_command_nm, man.torque_nm if man else nan, man.position_rad if man else nan,
            man.velocity_rad_s if man else nan,
        ))

    def _dwell(self, duration_s: float, phase: int) -> None:
        self._phase = phase
        self._velocity_rad_s = 0.0
        end = self._deadline + duration_s
        while True:
            self._cycle_once()
            if self._deadline >= end:
                return
