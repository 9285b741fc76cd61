"""The loop's named steps, each alone: pacing, the motor's books, the watchdogs' verdicts.

The whole loop is tested on the wire (test_watchdogs.py, test_loop_simulated.py); these pin down
each step's own rules with hand-made inputs, so a change to one shows where it broke.
"""

from __future__ import annotations

import math

import pytest

from bowden.control import Fault
from bowden.errors import DeviceTimeoutError, HardwareError, TransmitError
from bowden.hardware.protocols import ElevationSample, MotorState, TensionSample
from bowden.runtime.motor_link import MotorLink
from bowden.runtime.pacer import Pacer
from bowden.runtime.safety import SafetyConfig
from bowden.runtime.slack import SlackTakeUp
from bowden.runtime.timing import LoopTiming
from bowden.runtime.watchdogs import FINE, DeviceReader, Readings, Watchdogs


class ScriptedClock:
    """Wakes at the deadline plus the next scripted delay; ``now`` advances only by sleeping."""

    def __init__(self, delays: list[float]) -> None:
        self.t = 100.0
        self.delays = delays

    def now(self) -> float:
        return self.t

    def sleep_until(self, deadline_s: float) -> None:
        self.t = max(self.t, deadline_s) + (self.delays.pop(0) if self.delays else 0.0)


def test_the_pacer_keeps_absolute_deadlines_notes_stalls_and_skips_whole_periods():
    clock = ScriptedClock([0.0, 0.0005, 0.0, 0.025, 0.0])
    timing = LoopTiming(500.0)
    pacer = Pacer(clock, timing)
    pacer.start(clock.now())
    woke = []
    for _ in range(5):
        woke.append(pacer.wait() - pacer.t0)
        pacer.cycle_done(clock.now())
        pacer.advance()
    # 0, 2 ms (+0.5 ms late: not a stall), 4 ms, 6 ms + 25 ms: a stall of 25 ms beyond the period
    # (from the wake at 4 ms). The next deadline, 8 ms, is 23 ms past: 11 whole periods are skipped,
    # to 30 ms, which the loop meets at once (31 ms).
    assert woke == pytest.approx([0.0, 0.0025, 0.004, 0.031, 0.031])
    assert pacer.host_stalls == 1 and pacer.worst_stall_s == pytest.approx(0.025)
    assert pacer.fresh_since == pytest.approx(100.031)
    summary = timing.summary()
    assert summary.skipped_cycles == 11 and summary.cycles == 5


class Motor:
    """Answers per a script: a state, None (no reply yet), or an exception to raise."""

    def __init__(self, script: list[object]) -> None:
        self.script = script
        self.velocity_commands: list[tuple[float, float, float, float]] = []

    def command_torque(self, torque_nm: float) -> object:
        outcome = self.script.pop(0)
        if isinstance(outcome, Exception):
            raise outcome
        return outcome

    def command_mit(self, position: float, velocity: float, kp: float, kd: float) -> object:
        self.velocity_commands.append((position, velocity, kp, kd))
        return self.command_torque(0.0)


STATE = MotorState(0.0, 0.0, 0.0, 0.0, 30.0)


def test_the_motor_link_counts_commands_without_a_reply_from_the_oldest():
    motor = Motor([None, DeviceTimeoutError("late"), HardwareError("bad frame"), STATE, None])
    link = MotorLink(motor, None)  # type: ignore[arg-type]
    for now in (1.0, 1.002, 1.004):
        link.send(now, 0.5)
    assert (link.unanswered, link.oldest_unanswered_s, link.timeouts) == (3, 1.0, 3)
    assert link.malformed
    link.send(1.006, 0.5)  # a reply: the command just sent now awaits its own
    assert (link.reply, link.unanswered, link.oldest_unanswered_s, link.malformed) == (STATE, 1, 1.006, False)
    link.send(1.008, 0.0, 2.0, 0.3)
    assert motor.velocity_commands == [(0.0, 2.0, 0.0, 0.3)] and link.unanswered == 2


def test_transmit_failures_count_in_a_row_and_leave_the_reply_books_alone():
    link = MotorLink(Motor([TransmitError("ENOBUFS"), TransmitError("ENOBUFS"), STATE]), STATE)  # type: ignore[arg-type]
    link.send(1.0, 0.1)
    link.send(1.002, 0.1)
    assert (link.consecutive_transmit_failures, link.transmit_failures, link.unanswered) == (2, 2, 0)
    assert link.transmit_error == "ENOBUFS"
    link.send(1.004, 0.1)
    assert (link.consecutive_transmit_failures, link.transmit_failures) == (0, 2)


def readings(**values: float | str | None) -> Readings:
    r = Readings()
    r.elevation_rad, r.velocity_rad_s, r.imu_age_s = 1.0, 0.0, 0.002
    r.motor_velocity_rad_s, r.motor_torque_nm = 0.0, 0.5
    for name, value in values.items():
        setattr(r, name, value)
    return r


SAFETY = SafetyConfig()


@pytest.mark.parametrize(
    ("changes", "fault", "words"),
    [
        ({}, Fault.NONE, ""),
        ({"imu_age_s": 0.05}, Fault.IMU_STALE, "IMU: newest sample 50 ms old (limit 40 ms)"),
        ({"velocity_rad_s": math.nan}, Fault.NONFINITE_INPUT, "non-finite input"),
        ({"tension_n": 250.0}, Fault.TENSION_LIMIT, "load cell: 250.0 N above the 200 N limit"),
        ({"cell_problem": "load cell: 12 failed reads"}, Fault.LOAD_CELL_LOST, "the tension limit is blind"),
        ({"recording_problem": "disk full"}, Fault.RECORDER_FAILED, "recording failed: disk full"),
        # Most specific first: a stale IMU is named before the non-finite value it causes.
        ({"imu_age_s": 0.05, "elevation_rad": math.nan}, Fault.IMU_STALE, "IMU"),
    ],
)
def test_the_watchdogs_name_the_first_fault(changes, fault, words):
    link = MotorLink(Motor([]), STATE)  # type: ignore[arg-type]
    verdict = Watchdogs(SAFETY, None).judge(readings(**changes), link, 0.0, 10.0, 1.0, False)
    assert verdict[0] == fault and words in verdict[1]
    assert (verdict is FINE) == (fault == Fault.NONE)


def test_the_host_and_the_motor_come_before_the_sensors():
    link = MotorLink(Motor([None] * 5), STATE)  # type: ignore[arg-type]
    for i in range(5):
        link.send(10.0 + 0.002 * i, 0.1)
    stale = readings(imu_age_s=1.0)
    watchdogs = Watchdogs(SAFETY, None)
    assert watchdogs.judge(stale, link, 0.2, 10.04, 1.0, False)[0] == Fault.HOST_STALL
    fault, reason = watchdogs.judge(stale, link, 0.0, 10.04, 1.0, False)
    assert fault == Fault.MOTOR_NO_REPLY
    assert "no valid reply to the last 5 commands (the oldest sent 40 ms" in reason
    hot = MotorLink(Motor([]), MotorState(0.0, 0.0, 0.0, 0.0, 95.0))  # type: ignore[arg-type]
    assert watchdogs.judge(stale, hot, 0.0, 10.0, 1.0, False)[0] == Fault.MOTOR_OVER_TEMPERATURE


def test_a_slack_take_up_that_does_not_tighten_in_time_is_named():
    slack = SlackTakeUp()
    link = MotorLink(Motor([]), STATE)  # type: ignore[arg-type]
    watchdogs = Watchdogs(SAFETY, slack)
    assert watchdogs.judge(readings(), link, 0.0, 10.0, slack.timeout_s + 0.01, False) is FINE
    fault, reason = watchdogs.judge(readings(), link, 0.0, 10.0, slack.timeout_s + 0.01, True)
    assert fault == Fault.SLACK_NOT_TAKEN_UP and "is it attached?" in reason


class Imu:
    def __init__(self, sample: ElevationSample | None) -> None:
        self.sample = sample

    def read(self) -> ElevationSample | None:
        return self.sample


class LoadCell:
    def __init__(self, sample: TensionSample | None, failure: str | None = None) -> None:
        self.sample, self.failure = sample, failure

    def read(self) -> TensionSample | None:
        return self.sample


def test_sample_ages_count_from_when_the_loop_could_read_them():
    imu = Imu(ElevationSample(5.0, 1.0, 0.1))
    cell = LoadCell(TensionSample(5.0, 40.0))
    reader = DeviceReader(imu, cell, 0.25, None)  # type: ignore[arg-type]
    r = reader.read(5.3, 5.0, STATE)
    assert r.imu_age_s == pytest.approx(0.3)
    assert r.cell_problem == "load cell: no reading for 300 ms (limit 250 ms)"
    r = reader.read(5.3, 5.29, STATE)  # the loop itself stalled until 5.29: the samples are 10 ms old to it
    assert r.imu_age_s == pytest.approx(0.01) and r.cell_problem == "" and r.tension_n == 40.0
    assert (r.motor_velocity_rad_s, r.motor_torque_nm) == (0.0, 0.0)


def test_a_lost_load_cell_is_named_and_not_read_once_the_loop_runs_on_without_it():
    reader = DeviceReader(Imu(None), LoadCell(None, "load cell: 12 failed reads"), 0.25, lambda: None)  # type: ignore[arg-type]
    r = reader.read(1.0, 1.0, None)
    assert r.cell_problem == "load cell: 12 failed reads" and math.isinf(r.imu_age_s)
    assert math.isnan(r.motor_torque_nm) and r.recording_problem is None
    reader.cell_lost = True
    assert reader.read(1.0, 1.0, None).cell_problem == ""
