"""Fault injection over the wire: one test per fault, each ending in the safe state, measured on the bus.

The loop runs on the real clock with its default watchdogs (those a test does not inject into made
patient, below) against the simulated suit through its
peers (AK60 on virtual CAN, NGIMU over UDP, ADS1115 on the fake I²C bus). A fault is injected from
the recorder tap once the loop has run 0.15 s; the test then checks: the right watchdog fired, for the
logged reason, not before the fault existed; the torque followed the ramp to zero; motor mode was
exited (the exit frame is the driver's last frame). Latencies are taken from the CAN frames a sniffer
saw (zero-torque command, exit frame) against the wall time of the injection. Their budget (80 ms to
zero torque, 100 ms to the exit frame) is asserted only up to what the host itself added — the loop's
measured lateness and stalls — so that a busy machine cannot fail the test while a loop that is slow by
its own fault still does. ``benchmarks/faults.py`` prints the latencies themselves.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import sqlite3
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import can
import pytest

from bowden.control import Controller, Fault
from bowden.errors import StoreError
from bowden.hardware.ak60_codec import (
    DEFAULT_FIRMWARE,
    ENTER_MOTOR_MODE,
    EXIT_MOTOR_MODE,
    FIRMWARE_LIMITS,
    MotorErrorCode,
    unpack_command,
)
from bowden.runtime import (
    ControlLoop,
    LoopConfig,
    LoopReport,
    LoopState,
    Recorder,
    Row,
    SafetyConfig,
    TrialInfo,
    stop_on_signals,
)
from bowden.runtime import recorder as recorder_module
from bowden.runtime.clock import MonotonicClock
from bowden.runtime.realtime import RealtimeConfig
from bowden.store.sample_chunks import sample_count

if TYPE_CHECKING:
    from conftest import Rig

RATE_HZ = 500.0
INJECT_AT_S = 0.15
# The default watchdogs, but for the host-stall bound: the peers here are threads of the test process,
# so a busy machine stalls them with the loop (host stalls have their own tests, on the suit's clock
# and through bowden run with the suit in its own process).
DEFAULTS = SafetyConfig(max_tension_n=120.0, host_stall_max_s=2.0)
# For the same reason, the silence watchdogs a test does not inject into wait a second: a busy host
# starving the peer threads for 30 ms must not make "no reply" beat the fault under test.
PATIENT_MOTOR = replace(DEFAULTS, motor_max_silence_s=1.0)
PATIENT_IMU = replace(DEFAULTS, imu_max_age_s=1.0)
PATIENT = replace(DEFAULTS, motor_max_silence_s=1.0, imu_max_age_s=1.0)
ZERO_BUDGET_S = 0.080
EXIT_BUDGET_S = 0.100
LIMITS = FIRMWARE_LIMITS[DEFAULT_FIRMWARE]
TORQUE_LSB_NM = 2.0 * LIMITS.torque_nm / 4095.0


class Tap:
    """Collects rows and fires ``inject`` once, at the first cycle at or after ``INJECT_AT_S``."""

    def __init__(self, inject: Callable[[], None]) -> None:
        self.rows: list[Row] = []
        self.inject = inject
        self.injected_at_s: float | None = None
        self.injected_wall_s = float("nan")

    def __call__(self, row: Row) -> None:
        self.rows.append(row)
        if self.injected_at_s is None and row[0] >= INJECT_AT_S:
            self.injected_at_s = row[0]
            self.injected_wall_s = time.time()  # the sniffer's frames carry time.time() stamps
            self.inject()


def make_loop(rig: Rig, controller: Controller, tap: Tap, safety: SafetyConfig = PATIENT,
              duration_s: float = 3.0, **extra: object) -> ControlLoop:
    """The loop with ``bowden run``'s real-time settings: where the OS allows, it and the peers'
    threads (the devices' own processors; they share the loop's interpreter lock) run under
    ``SCHED_FIFO``, so another test worker does not starve them (a motor peer silent for 118 ms
    in CI, 2026-11-27). The arm starts its cycle now."""
    rig.start_moving()
    return ControlLoop(
        controller=controller, motor=rig.motor, elevation_sensor=rig.imu, clock=MonotonicClock(),
        config=LoopConfig(rate_hz=RATE_HZ, duration_s=duration_s, safety=safety),
        tension_sensor=rig.load_cell, record=tap, realtime=RealtimeConfig(),
        **extra,  # type: ignore[arg-type]
    )


def run(rig: Rig, controller: Controller, inject: Callable[[], None],
        safety: SafetyConfig = PATIENT, duration_s: float = 3.0) -> tuple[LoopReport, Tap]:
    """The loop until its fault (a fault's test), or ``duration_s`` (long enough for every fault)."""
    tap = Tap(inject)
    return make_loop(rig, controller, tap, safety, duration_s).run(), tap


@dataclass
class BusTimes:
    zero_s: float  # first zero-torque command after the injection, s after it
    exit_s: float  # the exit frame, s after the injection


def host_delay_s(report: LoopReport) -> float:
    """What the host added to a stop: the loop's worst wake-up lateness and its worst stall."""
    return report.timing.worst_lateness_s + report.worst_host_stall_s


def check_safe_stop(rig: Rig, report: LoopReport, tap: Tap, fault: Fault, reason: str,
                    caplog: pytest.LogCaptureFixture, *, cause_wall_s: float | None = None) -> None:
    """The safe stop, and its latencies on the bus from the cause (default: the injection)."""
    assert report.fault == fault, report.reason
    assert reason in report.reason
    assert any(reason in record.getMessage() for record in caplog.records), "reason not logged"
    assert tap.injected_at_s is not None
    # Nothing fired before the fault was injected.
    assert report.stop_time_s >= tap.injected_at_s
    assert all(row[10] == LoopState.RUNNING for row in tap.rows if row[0] < report.stop_time_s)
    # The ramp: from the last assisted torque to zero, never above the linear envelope.
    ramp = [row for row in tap.rows if row[10] == LoopState.RAMPING_DOWN]
    assert ramp and ramp[0][0] == report.stop_time_s
    start_torque = ramp[0][6]
    ramp_s = DEFAULTS.ramp_down_s
    for row in ramp:
        elapsed = row[0] - report.stop_time_s
        envelope = start_torque * max(0.0, 1.0 - elapsed / ramp_s)
        assert 0.0 <= row[6] <= envelope + 1e-12
        assert row[11] & int(fault) == int(fault)  # the fault is in every ramp row's flags
    assert ramp[-1][6] == 0.0
    assert report.zero_torque_time_s - report.stop_time_s <= ramp_s + 1.0 / RATE_HZ + host_delay_s(report)
    # Motor mode exited: the last frame the driver put on the bus is the exit frame.
    frames = [frame for frame in rig.frames() if frame.arbitration_id == rig.motor.config.motor_id]
    assert bytes(frames[-1].data) == EXIT_MOTOR_MODE
    assert report.motor_disabled and not rig.motor.enabled
    times = bus_times_from(frames, tap.injected_wall_s if cause_wall_s is None else cause_wall_s)
    slack = host_delay_s(report)
    note_latencies(fault, times, slack)
    assert times.zero_s <= ZERO_BUDGET_S + slack, (times, report.describe_health())
    assert times.exit_s <= EXIT_BUDGET_S + slack, (times, report.describe_health())


def note_latencies(fault: Fault, times: BusTimes, slack: float) -> None:
    """Append the measured latencies to $BOWDEN_FAULT_LATENCIES (benchmarks/faults.py prints them)."""
    path = os.environ.get("BOWDEN_FAULT_LATENCIES")
    if path:
        with open(path, "a", encoding="utf-8") as out:
            out.write(json.dumps({"test": os.environ.get("PYTEST_CURRENT_TEST", "").split(" ")[0],
                                  "fault": fault.name, "zero_s": times.zero_s, "exit_s": times.exit_s,
                                  "host_delay_s": slack}) + "\n")


def bus_times_from(frames: list[can.Message], cause_wall_s: float) -> BusTimes:
    """Latencies from ``cause_wall_s`` to the first zero-torque command and to the exit frame."""
    zero = exit_ = float("inf")
    for frame in frames:
        if frame.timestamp < cause_wall_s:
            continue
        data = bytes(frame.data)
        if data == EXIT_MOTOR_MODE:
            exit_ = min(exit_, frame.timestamp - cause_wall_s)
        elif data != ENTER_MOTOR_MODE and abs(unpack_command(data, LIMITS).torque_nm) <= TORQUE_LSB_NM:
            zero = min(zero, frame.timestamp - cause_wall_s)
    return BusTimes(zero, exit_)


def test_imu_silent(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    report, tap = run(rig, controller, rig.imu_peer.pause, PATIENT_MOTOR)
    # The IMU falls silent after its last sample, which a preempted peer thread may send after the
    # pause (a sample reached the loop 64 ms after it once, on a host running three test workers):
    # the budget runs from the last sample sent.
    silent_from_s = max(tap.injected_wall_s, rig.imu_peer.last_sent_wall_s)
    check_safe_stop(rig, report, tap, Fault.IMU_STALE, "IMU: newest sample", caplog,
                    cause_wall_s=silent_from_s)
    # The watchdog waited for the age limit (the IMU stopped at the injection, or earlier if its
    # thread was late on a busy machine).
    age_ms = int(report.reason.split("newest sample ")[1].split(" ms")[0])
    assert age_ms >= 1e3 * DEFAULTS.imu_max_age_s
    assert rig.peer_leaves_motor_mode()


def test_imu_nan(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    report, tap = run(rig, controller, rig.imu_peer.send_nan)
    check_safe_stop(rig, report, tap, Fault.NONFINITE_INPUT, "non-finite input", caplog)
    assert rig.peer_leaves_motor_mode()


def test_motor_silent(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    report, tap = run(rig, controller, rig.motor_peer.mute, PATIENT_IMU)
    check_safe_stop(rig, report, tap, Fault.MOTOR_NO_REPLY, "motor: no valid reply", caplog)
    # It waited for the limits: ≥ 5 commands unanswered, the oldest sent ≥ 30 ms before (replies to
    # commands sent just before the mute, still unanswered then, count too).
    count = int(report.reason.split("the last ")[1].split(" commands")[0])
    age_ms = int(report.reason.split("the oldest sent ")[1].split(" ms")[0])
    assert count >= DEFAULTS.motor_min_unanswered and age_ms >= 1e3 * DEFAULTS.motor_max_silence_s
    assert report.motor_timeouts >= DEFAULTS.motor_min_unanswered


def test_bad_replies(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    report, tap = run(rig, controller, lambda: rig.motor_peer.garble_replies(True), PATIENT_IMU)
    check_safe_stop(rig, report, tap, Fault.MOTOR_NO_REPLY, "(malformed frames)", caplog)
    assert rig.motor.counters.malformed >= DEFAULTS.motor_min_unanswered


@pytest.mark.parametrize("code", [MotorErrorCode.OVER_CURRENT, MotorErrorCode.ENCODER])
def test_motor_error_code(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture,
                          code: MotorErrorCode) -> None:
    caplog.set_level(logging.INFO)
    report, tap = run(rig, controller, lambda: rig.motor_peer.inject_error(int(code)))
    check_safe_stop(rig, report, tap, Fault.MOTOR_ERROR, MotorErrorCode.describe(code), caplog)
    assert rig.peer_leaves_motor_mode()


def test_motor_over_temperature(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    report, tap = run(rig, controller, lambda: rig.motor_peer.override_temperature(95.0))
    check_safe_stop(rig, report, tap, Fault.MOTOR_OVER_TEMPERATURE, "motor temperature 95 °C", caplog)
    assert rig.peer_leaves_motor_mode()


def test_tension_limit(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    report, tap = run(rig, controller, lambda: rig.adc.override_tension_n(300.0))
    check_safe_stop(rig, report, tap, Fault.TENSION_LIMIT, "above the 120 N limit", caplog)
    assert rig.peer_leaves_motor_mode()


def test_load_cell_lost_stops(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    report, tap = run(rig, controller, lambda: rig.adc.fail_next(10**9))
    check_safe_stop(rig, report, tap, Fault.LOAD_CELL_LOST, "the tension limit is blind", caplog)
    assert "load cell: no reading for" in report.reason or "I²C errors" in report.reason


def test_load_cell_lost_then_overload_never_goes_unnoticed(rig: Rig, controller: Controller,
                                                          caplog: pytest.LogCaptureFixture) -> None:
    """The measured failure: a lost load cell followed by 260 N. Either policy makes it visible."""
    caplog.set_level(logging.INFO)

    def lose_then_overload() -> None:
        rig.adc.fail_next(10**9)
        rig.adc.override_tension_n(260.0)

    # The loop runs to its end (no fault): 1 s, the loss at 0.15 s and most of the trial after it.
    report, tap = run(rig, controller, lose_then_overload, replace(PATIENT, on_load_cell_lost="continue"),
                      duration_s=1.0)
    # Degraded, explicitly: every row after the loss carries the flag, the summary says it.
    assert report.fault == Fault.NONE and "duration" in report.reason
    lost = [row for row in tap.rows if row[11] & int(Fault.LOAD_CELL_LOST)]
    assert lost and lost[0][0] >= INJECT_AT_S
    assert all(row[11] & int(Fault.LOAD_CELL_LOST) for row in tap.rows if row[0] >= lost[0][0])
    assert any("load cell lost" in text for text in report.degraded)
    assert "load cell lost" in report.describe_health()
    assert any("load cell lost" in record.getMessage() for record in caplog.records)


def test_recorder_backlog_stops(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture,
                                tmp_path: Path) -> None:
    """A writer that cannot write (another program holds the store locked) reaches the loop."""
    caplog.set_level(logging.INFO)
    store = tmp_path / "study.db"
    trial = TrialInfo(participant="P01", condition="support_50", speed="V1", support=0.5)
    recorder = Recorder(store, trial, max_backlog_rows=40).start()
    blocker = sqlite3.connect(store, timeout=10.0)
    try:
        tap = Tap(lambda: blocker.execute("BEGIN EXCLUSIVE"))
        sinks = [tap, recorder.record]
        loop = make_loop(rig, controller, tap, recorder_failure=lambda: recorder.failure,
                         on_event=recorder.event)
        loop.record = lambda row: [sink(row) for sink in sinks]  # type: ignore[func-returns-value]
        report = loop.run()
        # Measured from the moment the backlog passed its bound (the failure), not from the lock.
        check_safe_stop(rig, report, tap, Fault.RECORDER_FAILED, "rows waiting to be written", caplog,
                        cause_wall_s=recorder.failed_at_utc_s)
    finally:
        blocker.rollback()
        blocker.close()
    recorder.close(stop_reason=report.reason)  # the lock is gone: the backlog is written after all
    with sqlite3.connect(store) as check:
        rows = sample_count(check)
        reason = check.execute("SELECT stop_reason FROM trials").fetchone()[0]
    assert rows == len(tap.rows)  # nothing the loop handed over was lost
    assert "recording failed" in reason


def test_a_writer_that_dies_stops_the_loop_and_counts_its_rows(
    rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture, tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A writer killed by an error nobody foresaw (here a bug in its commit) still reaches the loop,
    which stops safely; every row the loop handed over is either in the store or counted as dropped."""
    caplog.set_level(logging.INFO)
    broken = False
    commit = recorder_module._TrialChunks.commit

    def commit_until_broken(self: object, *args: object, **kwargs: object) -> None:
        if broken:
            raise ValueError("injected: a bug in the writer")
        commit(self, *args, **kwargs)  # type: ignore[arg-type]

    def breaks() -> None:
        nonlocal broken
        broken = True

    monkeypatch.setattr(recorder_module._TrialChunks, "commit", commit_until_broken)
    store = tmp_path / "study.db"
    recorder = Recorder(store, TrialInfo(participant="P01", condition="support_50", speed="V1")).start()
    tap = Tap(breaks)
    sinks = [tap, recorder.record]
    loop = make_loop(rig, controller, tap, recorder_failure=lambda: recorder.failure, on_event=recorder.event)
    loop.record = lambda row: [sink(row) for sink in sinks]  # type: ignore[func-returns-value]
    report = loop.run()
    check_safe_stop(rig, report, tap, Fault.RECORDER_FAILED, "injected: a bug in the writer", caplog,
                    cause_wall_s=recorder.failed_at_utc_s)
    with pytest.raises(StoreError, match="injected"):
        recorder.close(stop_reason=report.reason)
    with sqlite3.connect(store) as check:
        stored = sample_count(check)
    assert stored == recorder.stats.committed_rows
    assert stored + recorder.stats.dropped_rows == len(tap.rows)


class FlakyBus(can.BusABC):  # type: ignore[misc]
    """The driver's end of the bus, whose transmissions fail (errno 105) while ``broken`` is set.

    ``broken`` clears itself after ``heal_after`` failed sends (a bus-off recovered by restart-ms),
    or never when None.
    """

    def __init__(self, inner: can.BusABC, heal_after: int | None) -> None:
        super().__init__(channel=inner.channel_info)
        self.inner = inner
        self.heal_after = heal_after
        self.broken = False
        self.failed = 0

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self.broken:
            self.failed += 1
            if self.heal_after is not None and self.failed >= self.heal_after:
                self.broken = False
            raise can.CanOperationError("No buffer space available", error_code=105)
        self.inner.send(msg, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return self.inner.recv(timeout), False

    def shutdown(self) -> None:
        super().shutdown()


@pytest.mark.parametrize("heal_after", [8, None])
def test_transmit_failure(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture,
                          heal_after: int | None) -> None:
    caplog.set_level(logging.INFO)
    from bowden.hardware.ak60 import AK60Motor

    flaky = FlakyBus(rig.motor._bus, heal_after)
    rig.motor = AK60Motor(flaky, rig.motor.config)

    def breaks() -> None:
        flaky.broken = True

    report, tap = run(rig, controller, breaks)
    assert report.fault == Fault.TRANSMIT_FAILED, report.reason
    assert "transmit failed 3 times in a row" in report.reason and "No buffer space" in report.reason
    assert report.transmit_failures >= DEFAULTS.max_transmit_failures
    if heal_after is not None:  # the bus came back: the ramp and the exit went out
        check_safe_stop(rig, report, tap, Fault.TRANSMIT_FAILED, "transmit failed", caplog)
    else:  # nothing can reach the motor: said, not raised; leaving the driver does not raise either
        assert not report.motor_disabled
        rig.motor.__exit__(None, None, None)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_signals_stop_within_one_cycle(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture,
                                       signum: signal.Signals) -> None:
    caplog.set_level(logging.INFO)
    tap = Tap(lambda: os.kill(os.getpid(), signum))
    loop = make_loop(rig, controller, tap)
    previous = signal.getsignal(signum)
    with stop_on_signals(loop.request_stop):
        report = loop.run()
    check_safe_stop(rig, report, tap, Fault.STOP_REQUESTED, f"signal {signum.name}", caplog)
    # The signal arrived during the injection cycle; the very next cycle began the ramp.
    times = [row[0] for row in tap.rows]
    assert times.index(report.stop_time_s) == times.index(tap.injected_at_s) + 1
    assert signal.getsignal(signum) is previous  # handler restored


def test_duration_ends_cleanly(rig: Rig, controller: Controller, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    tap = Tap(lambda: None)
    rig.start_moving()
    loop = ControlLoop(
        controller=controller, motor=rig.motor, elevation_sensor=rig.imu, clock=MonotonicClock(),
        config=LoopConfig(rate_hz=RATE_HZ, duration_s=0.3, safety=PATIENT), tension_sensor=rig.load_cell,
        record=tap, realtime=RealtimeConfig(),
    )
    report = loop.run()
    assert report.clean and report.fault == Fault.NONE
    assert report.stop_time_s >= 0.3 and "duration 0.3 s reached" in report.reason
    running = [row for row in tap.rows if row[10] == LoopState.RUNNING]
    # Assistance ran: the controller asked for tension and torque, the suit answered.
    assert max(row[6] for row in running) > 0.1
    assert all(row[4] >= 10.0 - 1e-9 for row in running)  # never below the 10 N floor
    assert report.timing.cycles == len(tap.rows)
