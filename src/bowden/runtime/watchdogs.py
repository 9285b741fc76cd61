"""What the loop reads each cycle, and the watchdogs that judge it.

Each watchdog judges the *device*, not the host: the motor is silent when replies are missing to
commands actually sent (:class:`~bowden.runtime.motor_link.MotorLink`), a sample's age counts from
when the loop could have read it (a stall of this process does not age the sensors), and a host
stall is its own condition, tolerated up to ``host_stall_max_s``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from bowden.control import Fault
from bowden.hardware.ak60_codec import MotorErrorCode
from bowden.hardware.protocols import ElevationSensor, MotorState, TensionSensor
from bowden.runtime.motor_link import MotorLink
from bowden.runtime.safety import SafetyConfig
from bowden.runtime.slack import SlackTakeUp

_NAN = math.nan
FINE = (Fault.NONE, "")  # the verdict when no watchdog fires (compare with `is`)


class Readings:
    """One cycle's inputs (NaN where a device gave nothing) and the evaluation devices' problems."""

    __slots__ = ("cell_problem", "elevation_rad", "imu_age_s", "motor_torque_nm", "motor_velocity_rad_s",
                 "recording_problem", "tension_n", "velocity_rad_s")

    def __init__(self) -> None:
        self.elevation_rad = self.velocity_rad_s = self.tension_n = _NAN
        self.motor_velocity_rad_s = self.motor_torque_nm = _NAN
        self.imu_age_s = math.inf
        self.cell_problem = ""
        self.recording_problem: str | None = None


class DeviceReader:
    """Reads the IMU, the load cell, the motor's latest reply and the recorder's health; never blocks.

    ``cell_lost`` and ``recording_lost`` (set by the loop once it runs on without them) stop reading
    those devices.
    """

    __slots__ = ("_cell", "_cell_max_age_s", "_imu", "_readings", "_recorder_failure", "cell_lost",
                 "recording_lost")

    def __init__(self, imu: ElevationSensor, load_cell: TensionSensor | None, cell_max_age_s: float,
                 recorder_failure: Callable[[], str | None] | None) -> None:
        self._imu = imu
        self._cell = load_cell
        self._cell_max_age_s = cell_max_age_s
        self._recorder_failure = recorder_failure
        self._readings = Readings()
        self.cell_lost = self.recording_lost = False

    def read(self, now: float, fresh_since: float, reply: MotorState | None) -> Readings:
        """This cycle's readings at clock time ``now`` (the same object every cycle, refilled)."""
        r = self._readings
        sample = self._imu.read()
        if sample is not None:
            r.elevation_rad = sample.elevation_rad
            r.velocity_rad_s = sample.elevation_velocity_rad_s
            r.imu_age_s = now - max(sample.time_s, fresh_since)
        else:
            r.elevation_rad = r.velocity_rad_s = _NAN
            r.imu_age_s = math.inf
        r.tension_n, r.cell_problem = _NAN, ""
        if self._cell is not None and not self.cell_lost:
            self._read_cell(r, now, fresh_since)
        if reply is not None:
            r.motor_velocity_rad_s, r.motor_torque_nm = reply.velocity_rad_s, reply.torque_nm
        else:
            r.motor_velocity_rad_s = r.motor_torque_nm = _NAN
        r.recording_problem = None
        if self._recorder_failure is not None and not self.recording_lost:
            r.recording_problem = self._recorder_failure()
        return r

    def _read_cell(self, r: Readings, now: float, fresh_since: float) -> None:
        cell = self._cell
        assert cell is not None
        sample = cell.read()
        failure = cell.failure
        if sample is not None:
            r.tension_n = sample.tension_n
            age = now - max(sample.time_s, fresh_since)
        else:
            age = now - fresh_since
        if failure is not None:
            r.cell_problem = failure
        elif age > self._cell_max_age_s:
            r.cell_problem = (f"load cell: no reading for {1e3 * age:.0f} ms "
                              f"(limit {1e3 * self._cell_max_age_s:.0f} ms)")


class Watchdogs:
    """The watchdogs of a running loop, most specific first; each reason names what to check."""

    __slots__ = ("_safety", "_slack", "_stop_on_cell_lost", "_stop_on_recorder_failure")

    def __init__(self, safety: SafetyConfig, slack: SlackTakeUp | None) -> None:
        self._safety = safety
        self._slack = slack
        self._stop_on_cell_lost = safety.on_load_cell_lost == "stop"
        self._stop_on_recorder_failure = safety.on_recorder_failure == "stop"

    def judge(self, r: Readings, link: MotorLink, stall_s: float, now: float, t: float,
              taking_up_slack: bool) -> tuple[Fault, str]:
        """The first fault that fires, with its reason; ``(Fault.NONE, "")`` when none does."""
        safety = self._safety
        if stall_s > safety.host_stall_max_s:
            return Fault.HOST_STALL, (f"host stall: the loop was not scheduled for {1e3 * stall_s:.0f} ms "
                                      f"(limit {1e3 * safety.host_stall_max_s:.0f} ms)")
        motor_fault = self._motor_fault(link, now)
        if motor_fault is not FINE:
            return motor_fault
        if r.imu_age_s > safety.imu_max_age_s:
            return Fault.IMU_STALE, (f"IMU: newest sample {1e3 * r.imu_age_s:.0f} ms old "
                                     f"(limit {1e3 * safety.imu_max_age_s:.0f} ms)")
        if not (math.isfinite(r.elevation_rad) and math.isfinite(r.velocity_rad_s)
                and math.isfinite(r.motor_velocity_rad_s) and math.isfinite(r.motor_torque_nm)):
            return Fault.NONFINITE_INPUT, (
                f"non-finite input: elevation {r.elevation_rad}, velocity {r.velocity_rad_s}, "
                f"motor velocity {r.motor_velocity_rad_s}, motor torque {r.motor_torque_nm}")
        if r.tension_n > safety.max_tension_n:
            return Fault.TENSION_LIMIT, (f"load cell: {r.tension_n:.1f} N above the "
                                         f"{safety.max_tension_n:.0f} N limit")
        if r.cell_problem and self._stop_on_cell_lost:
            return Fault.LOAD_CELL_LOST, f"{r.cell_problem}: the tension limit is blind"
        if r.recording_problem is not None and self._stop_on_recorder_failure:
            return Fault.RECORDER_FAILED, f"recording failed: {r.recording_problem}"
        slack = self._slack
        if taking_up_slack and slack is not None and t > slack.timeout_s:
            pull = slack.pull_n(r.tension_n, r.motor_torque_nm)
            return Fault.SLACK_NOT_TAKEN_UP, (f"slack take-up: the cable did not tighten to "
                                              f"{slack.pretension_n:g} N in {slack.timeout_s:g} s "
                                              f"(pull {pull:.1f} N): is it attached?")
        return FINE

    def _motor_fault(self, link: MotorLink, now: float) -> tuple[Fault, str]:
        safety = self._safety
        if link.consecutive_transmit_failures >= safety.max_transmit_failures:
            return Fault.TRANSMIT_FAILED, (f"motor: CAN transmit failed {link.consecutive_transmit_failures} "
                                           f"times in a row ({link.transmit_error})")
        if (link.unanswered >= safety.motor_min_unanswered
                and now - link.oldest_unanswered_s > safety.motor_max_silence_s):
            reason = (f"motor: no valid reply to the last {link.unanswered} commands "
                      f"(the oldest sent {1e3 * (now - link.oldest_unanswered_s):.0f} ms ago)")
            return Fault.MOTOR_NO_REPLY, reason + (" (malformed frames)" if link.malformed else "")
        reply = link.reply
        if reply is not None and reply.error_code != 0:
            code = reply.error_code
            return Fault.MOTOR_ERROR, f"motor error code {code}: {MotorErrorCode.describe(code)}"
        if reply is not None and reply.temperature_c > safety.max_temperature_c:
            return Fault.MOTOR_OVER_TEMPERATURE, (f"motor temperature {reply.temperature_c:.0f} °C "
                                                  f"above {safety.max_temperature_c:.0f} °C")
        return FINE
