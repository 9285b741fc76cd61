"""Fault injection over the wire: one test per watchdog, each ending in the safe state in time.

The loop runs on the real clock against the simulated suit through its peers (AK60 on virtual CAN,
NGIMU over UDP, ADS1115 on the fake I²C bus). A fault is injected from the recorder tap once the
loop has run 0.15 s; the test then checks, on the loop's own timeline: the right watchdog fired, for
the logged reason, not before the fault existed; the torque followed the ramp and reached zero within
100 ms; motor mode was exited (the exit frame is on the bus after the last command).
"""

from __future__ import annotations

import logging
import os
import signal
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import pytest

from bowden.control import Controller, Fault
from bowden.hardware.ak60_codec import EXIT_MOTOR_MODE, MotorErrorCode
from bowden.runtime import ControlLoop, LoopConfig, LoopReport, LoopState, Row, SafetyConfig, stop_on_signals
from bowden.runtime.clock import MonotonicClock

if TYPE_CHECKING:
    from conftest import Rig

RATE_HZ = 500.0
INJECT_AT_S = 0.15
# The watchdogs not under test get lenient limits so that a busy shared machine (a thread starved for
# tens of ms) cannot fire them first; each test tightens the one it exercises to its default.
SAFETY = SafetyConfig(ramp_down_s=0.05, max_temperature_c=80.0, max_tension_n=120.0,
                      imu_max_age_s=0.3, motor_max_silence_s=0.3)
STRICT_IMU = replace(SAFETY, imu_max_age_s=0.05)
STRICT_MOTOR = replace(SAFETY, motor_max_silence_s=0.02)


class Tap:
    """Collects rows and fires ``inject`` once, at the first cycle at or after ``INJECT_AT_S``."""

    def __init__(self, inject: Callable[[], None]) -> None:
        self.rows: list[Row] = []
        self.inject = inject
        self.injected_at_s: float | None = None

    def __call__(self, row: Row) -> None:
        self.rows.append(row)
        if self.injected_at_s is None and row[0] >= INJECT_AT_S:
            self.injected_at_s = row[0]
            self.inject()


def run(rig: Rig, controller: Controller, inject: Callable[[], None],
        safety: SafetyConfig = SAFETY) -> tuple[LoopReport, Tap]:
    tap = Tap(inject)
    loop = ControlLoop(
        controller=controller, motor=rig.motor, elevation_sensor=rig.imu, clock=MonotonicClock(),
        config=LoopConfig(rate_hz=RATE_HZ, duration_s=3.0, safety=safety),
        tension_sensor=rig.load_cell, record=tap,
    )
    return loop.run(), tap


def check_safe_stop(rig: Rig, report: LoopReport, tap: Tap, fault: Fault, reason: str,
                    caplog: pytest.LogCaptureFixture) -> None:
    assert report.fault == fault, report.reason
    assert reason in report.reason
    assert any(reason in record.getMessage() for record in caplog.records), "reason not logged"
    assert tap.injected_at_s is not None
    # Nothing fired before the fault was injected.
    assert report.stop_time_s >= tap.injected_at_s
    assert all(row[10] == LoopState.RUNNING for row in tap.rows if row[0] < report.stop_time_s)
    # The ramp: from the last assisted torque to zero, never above the linear envelope, zero in time.
    ramp = [row for row in tap.rows if row[10] == LoopState.RAMPING_DOWN]
    assert ramp and ramp[0][0] == report.stop_time_s
    start_torque = ramp[0][6]
    for row in ramp:
        elapsed = row[0] - report.stop_time_s
        envelope = start_torque * max(0.0, 1.0 - elapsed / SAFETY.ramp_down_s)
        assert 0.0 <= row[6] <= envelope + 1e-12
        assert row[11] & int(fault) == int(fault)  # the fault is in every ramp row's flags
    assert ramp[-1][6] == 0.0
    assert report.zero_torque_time_s - report.stop_time_s <= 0.1
    # Motor mode exited: the last frame the driver put on the bus is the exit frame.
    frames = [frame for frame in rig.frames() if frame.arbitration_id == rig.motor.config.motor_id]
    assert bytes(frames[-1].data) == EXIT_MOTOR_MODE
    assert report.motor_disabled and not rig.motor.enabled


def test_imu_stale(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    report, tap = run(rig, controller, rig.imu_peer.pause, STRICT_IMU)
    check_safe_stop(rig, report, tap, Fault.IMU_STALE, "IMU: newest sample", caplog)
    # The IMU stopped at injection; the watchdog waits for the 50 ms age limit (less one IMU period).
    assert report.stop_time_s - tap.injected_at_s >= STRICT_IMU.imu_max_age_s - 1.0 / 400.0
    assert not rig.motor_peer.in_motor_mode


def test_motor_reply_missing(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    report, tap = run(rig, controller, rig.motor_peer.mute, STRICT_MOTOR)
    check_safe_stop(rig, report, tap, Fault.MOTOR_NO_REPLY, "motor: no valid reply", caplog)
    assert report.stop_time_s - tap.injected_at_s >= STRICT_MOTOR.motor_max_silence_s - 1.0 / RATE_HZ
    assert report.motor_timeouts > 0


def test_non_finite_input(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    report, tap = run(rig, controller, rig.imu_peer.send_nan)
    check_safe_stop(rig, report, tap, Fault.NONFINITE_INPUT, "non-finite input", caplog)
    assert not rig.motor_peer.in_motor_mode


@pytest.mark.parametrize("code", [MotorErrorCode.OVER_CURRENT, MotorErrorCode.ENCODER])
def test_motor_error_code(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture,
                          code: MotorErrorCode) -> None:
    caplog.set_level(logging.INFO)
    report, tap = run(rig, controller, lambda: rig.motor_peer.inject_error(int(code)))
    check_safe_stop(rig, report, tap, Fault.MOTOR_ERROR, MotorErrorCode.describe(code), caplog)
    assert not rig.motor_peer.in_motor_mode


def test_motor_over_temperature(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    report, tap = run(rig, controller, lambda: rig.motor_peer.override_temperature(95.0))
    check_safe_stop(rig, report, tap, Fault.MOTOR_OVER_TEMPERATURE, "motor temperature 95 °C", caplog)
    assert not rig.motor_peer.in_motor_mode


def test_tension_limit(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    report, tap = run(rig, controller, lambda: rig.adc.override_tension_n(300.0))
    check_safe_stop(rig, report, tap, Fault.TENSION_LIMIT, "above the 120 N limit", caplog)
    assert not rig.motor_peer.in_motor_mode


def test_sigterm_stops_within_one_cycle(rig: Rig, controller: Controller,
                                        caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    tap = Tap(lambda: os.kill(os.getpid(), signal.SIGTERM))
    loop = ControlLoop(
        controller=controller, motor=rig.motor, elevation_sensor=rig.imu, clock=MonotonicClock(),
        config=LoopConfig(rate_hz=RATE_HZ, duration_s=3.0, safety=SAFETY), record=tap,
    )
    with stop_on_signals(loop.request_stop):
        report = loop.run()
    check_safe_stop(rig, report, tap, Fault.STOP_REQUESTED, "signal SIGTERM", caplog)
    # The signal arrived during the injection cycle; the very next cycle began the ramp.
    times = [row[0] for row in tap.rows]
    assert times.index(report.stop_time_s) == times.index(tap.injected_at_s) + 1
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # handler restored


def test_duration_ends_cleanly(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    tap = Tap(lambda: None)
    loop = ControlLoop(
        controller=controller, motor=rig.motor, elevation_sensor=rig.imu, clock=MonotonicClock(),
        config=LoopConfig(rate_hz=RATE_HZ, duration_s=0.3, safety=SAFETY), tension_sensor=rig.load_cell,
        record=tap,
    )
    report = loop.run()
    assert report.clean and report.fault == Fault.NONE
    assert report.stop_time_s >= 0.3 and "duration 0.3 s reached" in report.reason
    running = [row for row in tap.rows if row[10] == LoopState.RUNNING]
    # Assistance ran: the controller asked for tension and torque, the suit answered.
    assert max(row[6] for row in running) > 0.1
    assert all(row[4] >= 10.0 - 1e-9 for row in running)  # never below the 10 N floor
    assert report.timing.cycles == len(tap.rows)
