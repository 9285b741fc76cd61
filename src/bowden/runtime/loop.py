"""The fixed-rate control loop: IMU → controller → motor, with watchdogs and a recorder tap.

Each cycle, on absolute deadlines ``t₀ + k/rate`` of the injected clock (no drift: a late cycle does
not delay the next deadline; when the loop falls behind by whole periods it skips to the next
deadline and counts the skipped cycles as misses):

1. note how long the loop itself was not scheduled (a *host stall*: the time since the previous
   cycle began, beyond one period); read the latest elevation sample and the latest tension sample
   (never blocks);
2. run the watchdogs — each judges the *device*, not the host: the motor is silent when replies are
   missing to commands actually sent (a count and the age of the oldest unanswered send), a sample's
   age counts from when the loop could have read it (a stall of this process does not age the
   sensors), and a host stall is its own condition, tolerated up to ``host_stall_max_s``. Then
   non-finite inputs, a motor error code, over-temperature, tension above the limit, a lost load
   cell, a failed recorder, repeated transmit failures, a stop request (SIGINT/SIGTERM) or the end;
3. while running, ``controller.step(...)`` gives the torque; once a watchdog fired, the torque ramps
   to zero over ``ramp_down_s`` and then motor mode is exited (:mod:`bowden.runtime.safety`);
4. send the torque without waiting (the motor's newest reply serves the next cycle), hand one row to
   the recorder (non-blocking).

The same loop drives the real suit (AK60 over CAN, NGIMU over UDP, ``MonotonicClock``), the
simulated suit in its own process through the same drivers, or the simulated suit directly with its
own clock (fast). The body is plain Python on floats; logging happens only when the state changes.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass, field, replace
from typing import Protocol

from bowden.control import Command, Fault
from bowden.errors import DeviceTimeoutError, HardwareError, ParameterError
from bowden.hardware.protocols import Clock, ElevationSensor, Motor, TensionSensor
from bowden.runtime.motor_link import MotorLink
from bowden.runtime.pacer import STALL_NOTICE_S, Pacer
from bowden.runtime.realtime import RealtimeConfig, realtime
from bowden.runtime.safety import LoopState, SafetyConfig, ramp_torque_nm
from bowden.runtime.slack import SlackTakeUp
from bowden.runtime.timing import LoopTiming, TimingSummary
from bowden.runtime.watchdogs import FINE, DeviceReader, Readings, Watchdogs

_log = logging.getLogger(__name__)
_NAN = math.nan

Row = tuple[float, float, float, float, float, float, float, float, float, float, int, int]
"""One trial-recording row, in the order of ``bowden.contracts.TRIAL_COLUMNS``."""


class StepController(Protocol):
    """What the loop needs of :class:`bowden.control.Controller`."""

    def step(
        self,
        time_s: float,
        elevation_rad: float,
        elevation_velocity_rad_s: float,
        motor_velocity_rad_s: float = _NAN,
        motor_torque_nm: float = _NAN,
    ) -> Command: ...


@dataclass(frozen=True, kw_only=True)
class LoopConfig:
    """Rate, duration and watchdogs of one run.

    Parameters
    ----------
    rate_hz
        Control rate (default 500 Hz; up to 2 kHz).
    duration_s
        Run length (s) after which the loop ramps down and stops; None runs until stopped.
    safety
        Watchdog thresholds and the safe-state ramp.
    slack
        Take up the cable's slack before assisting (:mod:`bowden.runtime.slack`): the first cycles
        reel in slowly in velocity mode, watched like every cycle, until the cable's pull (load
        cell, or motor torque over the pulley radius) reaches the pretension; then the controller
        takes over. Needs a motor with ``command_mit`` (the AK60 driver); None: assist at once.
    """

    rate_hz: float = 500.0
    duration_s: float | None = None
    safety: SafetyConfig = field(default_factory=SafetyConfig)
    slack: SlackTakeUp | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate_hz) and 1.0 <= self.rate_hz <= 2000.0):
            raise ParameterError(f"LoopConfig.rate_hz must be in [1, 2000] Hz, got {self.rate_hz!r}")
        if self.duration_s is not None and not (math.isfinite(self.duration_s) and self.duration_s > 0.0):
            raise ParameterError(f"LoopConfig.duration_s must be positive, got {self.duration_s!r}")


@dataclass(frozen=True)
class LoopReport:
    """How a run ended (times in s since the loop started, on its clock)."""

    reason: str
    fault: Fault
    cycles: int
    stop_time_s: float  # the watchdog fired or the stop began
    zero_torque_time_s: float  # first cycle commanding zero torque in the ramp
    safe_time_s: float  # motor mode exited
    motor_disabled: bool
    timing: TimingSummary
    motor_timeouts: int  # cycles whose command had brought no new motor reply by the next cycle
    controller_fault_cycles: int
    host_stalls: int = 0  # gaps between cycles over STALL_NOTICE_S beyond the period
    worst_host_stall_s: float = 0.0
    transmit_failures: int = 0
    degraded: tuple[str, ...] = ()  # states the run went on in (load cell lost, recording off)
    realtime: str = ""  # the real-time settings applied, or why not
    slack_take_up_s: float = math.nan  # loop time the slack was taken up (NaN: no take-up, or never)

    @property
    def clean(self) -> bool:
        """True when the run ended by its duration or a stop request, not by a watchdog."""
        return self.fault in (Fault.NONE, Fault.STOP_REQUESTED)

    def describe_health(self) -> str:
        """One line on what the host and the devices did (for the run summary)."""
        parts = [f"host stalls {self.host_stalls} (worst {1e3 * self.worst_host_stall_s:.0f} ms)",
                 f"cycles without a new motor reply {self.motor_timeouts}",
                 f"transmit failures {self.transmit_failures}"]
        parts.extend(self.degraded)
        return "; ".join(parts)


class _Run:
    """What one run has done so far: its state, why it stops, the torque it commands, its tallies."""

    __slots__ = ("controller_fault_cycles", "cycles", "degraded", "degraded_flags", "disabled", "fault",
                 "ramp_from", "reason", "safe_time", "slack_time", "state", "stop_time", "taking_up",
                 "torque", "zero_time")

    def __init__(self, *, taking_up: bool) -> None:
        self.state = LoopState.RUNNING
        self.fault = Fault.NONE
        self.reason = ""
        self.stop_time = self.zero_time = self.safe_time = self.slack_time = _NAN
        self.ramp_from = self.torque = 0.0
        self.taking_up = taking_up
        self.degraded: list[str] = []
        self.degraded_flags = 0
        self.controller_fault_cycles = self.cycles = 0
        self.disabled = False


class ControlLoop:
    """One run of the controller on a suit.

    Parameters
    ----------
    controller
        ``bowden.control.build_controller(...)``.
    motor, elevation_sensor
        The suit's motor and IMU (real drivers or simulated).
    clock
        The loop's clock; the sensors must time-stamp samples with the same clock.
    config
        :class:`LoopConfig`.
    tension_sensor
        Optional load cell (recorded; its limit is a watchdog; never used for control).
    record
        Called with one :data:`Row` per cycle; must not block (e.g. ``Recorder.record``).
    reference_elevation
        Reference elevation (rad) at loop time t, for the recording (NaN if None).
    recorder_failure
        Returns why the recording failed, or None while it works (e.g. ``lambda: recorder.failure``);
        read every cycle.
    on_event
        Called with (loop time s, kind, message) for what happened once (host stalls, degraded
        states); must not block (e.g. ``Recorder.event``).
    realtime
        Real-time settings for the loop's thread while it runs (None: leave the scheduling alone).
    """

    def __init__(
        self,
        *,
        controller: StepController,
        motor: Motor,
        elevation_sensor: ElevationSensor,
        clock: Clock,
        config: LoopConfig | None = None,
        tension_sensor: TensionSensor | None = None,
        record: Callable[[Row], None] | None = None,
        reference_elevation: Callable[[float], float] | None = None,
        recorder_failure: Callable[[], str | None] | None = None,
        on_event: Callable[[float, str, str], None] | None = None,
        realtime: RealtimeConfig | None = None,
    ) -> None:
        self.controller = controller
        self.motor = motor
        self.elevation_sensor = elevation_sensor
        self.clock = clock
        self.config = config if config is not None else LoopConfig()
        self.tension_sensor = tension_sensor
        self.record = record
        self.reference_elevation = reference_elevation
        self.recorder_failure = recorder_failure
        self.on_event = on_event
        self.realtime = realtime
        self.timing = LoopTiming(self.config.rate_hz)
        self._stop_reason: str | None = None
        self.state = LoopState.RUNNING

    def request_stop(self, reason: str = "stop requested") -> None:
        """Ask the loop to stop safely (thread- and signal-handler-safe: one attribute write)."""
        self._stop_reason = reason

    def _wait_for_imu(self) -> None:
        timeout = self.config.safety.imu_startup_timeout_s
        start = self.clock.now()
        step = 1.0 / self.config.rate_hz
        while self.elevation_sensor.read() is None:
            now = self.clock.now()
            if now - start > timeout:
                raise DeviceTimeoutError(
                    f"no elevation sample within {timeout} s: is the IMU streaming (and calibrated)?"
                )
            if self._stop_reason is not None:
                raise DeviceTimeoutError(f"stopped while waiting for the IMU ({self._stop_reason})")
            self.clock.sleep_until(now + step)

    def run(self) -> LoopReport:
        """Enable the motor, run until a watchdog, the duration or a stop request, end safe.

        Raises
        ------
        DeviceTimeoutError
            If the IMU sends nothing before the start (the motor is never enabled then).
        HardwareError
            If the motor cannot be put into motor mode.
        """
        self._wait_for_imu()
        with ExitStack() as stack:
            settings = ""
            if self.realtime is not None:
                settings = stack.enter_context(realtime(self.realtime)).describe()
            try:
                report = self._run()
            except BaseException:
                # An error the watchdogs do not cover (a bug, an interrupt mid-cycle): no ramp is
                # possible any more, so at least leave motor mode before the error goes up.
                self._disable_motor()
                raise
        return replace(report, realtime=settings)

    def _event(self, time_s: float, kind: str, message: str) -> None:
        if self.on_event is not None:
            self.on_event(time_s, kind, message)

    def _run(self) -> LoopReport:
        """The cycles: pace, read the devices, judge their health, command, send, record."""
        clock = self.clock
        slack = self.config.slack
        if slack is not None and getattr(self.motor, "command_mit", None) is None:
            _log.warning("slack take-up skipped: this motor has no velocity mode")
            slack = None
        run = _Run(taking_up=slack is not None)
        pacer = Pacer(clock, self.timing)
        reader = DeviceReader(self.elevation_sensor, self.tension_sensor,
                              self.config.safety.load_cell_max_age_s, self.recorder_failure)
        watchdogs = Watchdogs(self.config.safety, slack)
        duration = self.config.duration_s
        end_s = duration - 1e-9 if duration is not None else math.inf  # 1 ns: a cycle on the end, rounded
        link = MotorLink(self.motor, self.motor.enable())
        pacer.start(clock.now())
        while True:
            now = pacer.wait()
            t = now - pacer.t0
            if pacer.stall_s > STALL_NOTICE_S:
                self._note_stall(pacer.stall_s, t)
            readings = reader.read(now, pacer.fresh_since, link.reply)
            if run.state is LoopState.RUNNING:
                verdict = watchdogs.judge(readings, link, pacer.stall_s, now, t, run.taking_up)
                if verdict is not FINE or self._stop_reason is not None or t >= end_s:
                    self._stop(run, verdict, t)
            if readings.cell_problem or readings.recording_problem is not None:
                self._degrade(run, reader, readings, t)
            desired_tension, moment_arm, flags = self._command(run, readings, slack, t)
            if slack is not None and run.taking_up and run.state is LoopState.RUNNING:
                link.send(now, run.torque, slack.velocity_rad_s, slack.kd_nms_rad)
            else:
                link.send(now, run.torque)
            end = clock.now()
            if self.record is not None:  # a failed recorder counts what it can no longer write
                self._record(self.record, t, readings, desired_tension, moment_arm, run, flags)
            run.cycles += 1
            pacer.cycle_done(end)
            if run.state is LoopState.RAMPING_DOWN and run.zero_time == run.zero_time:
                run.disabled = self._disable_motor()
                run.safe_time = clock.now() - pacer.t0
                run.state = LoopState.SAFE
                _log.info("safe state reached at t = %.3f s (motor mode exited)", run.safe_time)
                break
            pacer.advance()
        self.state = run.state
        return self._report(run, link, pacer)

    def _note_stall(self, stall_s: float, t: float) -> None:
        stall_max = self.config.safety.host_stall_max_s
        if stall_s <= stall_max:  # a longer one is a fault, with its own reason
            self._event(t, "host_stall", f"loop not scheduled for {1e3 * stall_s:.0f} ms "
                        f"(tolerated up to {1e3 * stall_max:.0f} ms)")

    def _stop(self, run: _Run, verdict: tuple[Fault, str], t: float) -> None:
        """Start the safe stop: for a watchdog's fault, else a stop request, else the end of the duration."""
        fault, reason = verdict
        if fault == Fault.NONE:
            if self._stop_reason is not None:
                fault, reason = Fault.STOP_REQUESTED, self._stop_reason
            else:
                reason = f"duration {self.config.duration_s:g} s reached"
        run.fault, run.reason = fault, reason
        run.state = LoopState.RAMPING_DOWN
        run.stop_time, run.ramp_from = t, run.torque
        log = _log.info if fault in (Fault.NONE, Fault.STOP_REQUESTED) else _log.warning
        log("safe stop at t = %.3f s: %s; ramping %.2f Nm to zero in %.0f ms",
            t, reason, run.ramp_from, 1e3 * self.config.safety.ramp_down_s)

    def _degrade(self, run: _Run, reader: DeviceReader, readings: Readings, t: float) -> None:
        """Degraded states the operator chose to run on in: said once, flagged in every row after."""
        safety = self.config.safety
        if readings.cell_problem and not reader.cell_lost and safety.on_load_cell_lost != "stop":
            reader.cell_lost = True
            run.degraded_flags |= int(Fault.LOAD_CELL_LOST)
            run.degraded.append(f"load cell lost at t = {t:.3f} s ({readings.cell_problem}); "
                                "tension limit off")
            _log.warning("%s", run.degraded[-1])
            self._event(t, "degraded", run.degraded[-1])
        problem = readings.recording_problem
        if problem is not None and not reader.recording_lost and safety.on_recorder_failure != "stop":
            reader.recording_lost = True
            run.degraded_flags |= int(Fault.RECORDER_FAILED)
            run.degraded.append(f"recording failed at t = {t:.3f} s ({problem}); assisting without it")
            _log.error("%s", run.degraded[-1])

    def _command(self, run: _Run, r: Readings, slack: SlackTakeUp | None,
                 t: float) -> tuple[float, float, int]:
        """Set ``run.torque``; return the desired tension, the moment arm and the row's fault flags."""
        flags = int(run.fault) | run.degraded_flags
        running = run.state is LoopState.RUNNING
        if running and run.taking_up and slack is not None:
            pull = slack.pull_n(r.tension_n, r.motor_torque_nm)
            if pull >= slack.pretension_n:
                run.taking_up, run.slack_time = False, t
                self._event(t, "slack", f"slack taken up in {t:.2f} s ({pull:.1f} N)")
            else:
                # Reeling in: the motor's own velocity loop commands the torque (at most kd·v).
                run.torque = r.motor_torque_nm if math.isfinite(r.motor_torque_nm) else 0.0
                return _NAN, _NAN, flags
        if running:
            command = self.controller.step(t, r.elevation_rad, r.velocity_rad_s, r.motor_velocity_rad_s,
                                           r.motor_torque_nm)
            run.torque = command.torque_nm
            if command.faults:
                flags |= command.faults
                run.controller_fault_cycles += 1
            return command.tension_n, command.moment_arm_m, flags
        run.torque = ramp_torque_nm(run.ramp_from, t - run.stop_time, self.config.safety.ramp_down_s)
        if run.torque == 0.0 and run.zero_time != run.zero_time:
            run.zero_time = t
        return _NAN, _NAN, flags

    def _record(self, record: Callable[[Row], None], t: float, r: Readings, desired_tension: float,
                moment_arm: float, run: _Run, flags: int) -> None:
        reference = self.reference_elevation
        record((
            t,
            reference(t) if reference is not None else _NAN,
            r.elevation_rad,
            r.velocity_rad_s,
            desired_tension,
            moment_arm,
            run.torque,
            r.motor_torque_nm,
            r.motor_velocity_rad_s,
            r.tension_n,
            int(run.state),
            flags,
        ))

    def _report(self, run: _Run, link: MotorLink, pacer: Pacer) -> LoopReport:
        return LoopReport(
            reason=run.reason,
            fault=run.fault,
            cycles=run.cycles,
            stop_time_s=run.stop_time,
            zero_torque_time_s=run.zero_time,
            safe_time_s=run.safe_time,
            motor_disabled=run.disabled,
            timing=self.timing.summary(),
            motor_timeouts=link.timeouts,
            controller_fault_cycles=run.controller_fault_cycles,
            host_stalls=pacer.host_stalls,
            worst_host_stall_s=pacer.worst_stall_s,
            transmit_failures=link.transmit_failures,
            degraded=tuple(run.degraded),
            slack_take_up_s=run.slack_time,
        )

    def _disable_motor(self) -> bool:
        try:
            self.motor.disable()
        except HardwareError:
            # Nothing more can be done from here; the reason is in the log and the report.
            _log.exception("could not exit motor mode")
            return False
        return True
