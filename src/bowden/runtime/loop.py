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
from bowden.errors import DeviceTimeoutError, HardwareError, ParameterError, TransmitError
from bowden.hardware.ak60_codec import MotorErrorCode
from bowden.hardware.protocols import Clock, ElevationSensor, Motor, MotorState, TensionSensor
from bowden.runtime.realtime import RealtimeConfig, realtime
from bowden.runtime.safety import LoopState, SafetyConfig, ramp_torque_nm
from bowden.runtime.slack import SlackTakeUp
from bowden.runtime.timing import LoopTiming, TimingSummary

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


STALL_NOTICE_S = 0.01
"""A gap between cycles this much longer than the period counts (and is recorded) as a host stall."""


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
        safety = self.config.safety
        clock = self.clock
        motor = self.motor
        imu = self.elevation_sensor
        load_cell = self.tension_sensor
        controller = self.controller
        record = self.record
        reference = self.reference_elevation
        recorder_failure = self.recorder_failure
        timing = self.timing
        period = 1.0 / self.config.rate_hz
        duration = self.config.duration_s if self.config.duration_s is not None else math.inf
        imu_max_age = safety.imu_max_age_s
        motor_max_silence = safety.motor_max_silence_s
        motor_min_unanswered = safety.motor_min_unanswered
        max_transmit_failures = safety.max_transmit_failures
        stall_max = safety.host_stall_max_s
        max_temperature = safety.max_temperature_c
        max_tension = safety.max_tension_n
        cell_max_age = safety.load_cell_max_age_s
        stop_on_cell_lost = safety.on_load_cell_lost == "stop"
        stop_on_recorder_failure = safety.on_recorder_failure == "stop"
        ramp_s = safety.ramp_down_s
        isfinite = math.isfinite
        disabled = False
        slack = self.config.slack
        command_mit = getattr(motor, "command_mit", None)
        if slack is not None and command_mit is None:
            _log.warning("slack take-up skipped: this motor has no velocity mode")
            slack = None
        taking_up = slack is not None
        slack_time = _NAN

        reply: MotorState | None = motor.enable()
        t0 = clock.now()
        deadline = t0
        last_wake = t0 - period
        fresh_since = t0  # sample ages count from here at most: the loop could not read before it
        k = 0
        state = LoopState.RUNNING
        fault = Fault.NONE
        reason = ""
        stop_time = zero_time = safe_time = _NAN
        ramp_from = 0.0
        torque = 0.0
        motor_timeouts = 0
        unanswered = 0
        oldest_unanswered_s = _NAN
        controller_fault_cycles = 0
        transmit_failures = consecutive_transmit_failures = 0
        transmit_error = ""
        new_reply: MotorState | None = None
        motor_malformed = False
        host_stalls = 0
        worst_stall = 0.0
        degraded: list[str] = []
        degraded_flags = 0
        cell_lost = recording_lost = False
        cycles = 0

        while True:
            clock.sleep_until(deadline)
            now = clock.now()
            t = now - t0
            stall = now - last_wake - period
            last_wake = now
            if stall > STALL_NOTICE_S:
                host_stalls += 1
                fresh_since = now
                if stall > worst_stall:
                    worst_stall = stall
                if stall <= stall_max:
                    self._event(t, "host_stall", f"loop not scheduled for {1e3 * stall:.0f} ms "
                                f"(tolerated up to {1e3 * stall_max:.0f} ms)")
            sample = imu.read()
            tension = _NAN
            cell_problem = ""
            if load_cell is not None and not cell_lost:
                tension_sample = load_cell.read()
                failure = load_cell.failure
                if tension_sample is not None:
                    tension = tension_sample.tension_n
                    cell_age = now - max(tension_sample.time_s, fresh_since)
                else:
                    cell_age = now - fresh_since
                if failure is not None:
                    cell_problem = failure
                elif cell_age > cell_max_age:
                    cell_problem = (f"load cell: no reading for {1e3 * cell_age:.0f} ms "
                                    f"(limit {1e3 * cell_max_age:.0f} ms)")
            if sample is not None:
                elevation = sample.elevation_rad
                velocity = sample.elevation_velocity_rad_s
                imu_age = now - max(sample.time_s, fresh_since)
            else:
                elevation = velocity = _NAN
                imu_age = math.inf
            if reply is not None:
                motor_velocity = reply.velocity_rad_s
                motor_torque = reply.torque_nm
            else:
                motor_velocity = motor_torque = _NAN
            recording_problem = None
            if recorder_failure is not None and not recording_lost:
                recording_problem = recorder_failure()

            if state is LoopState.RUNNING:
                # Watchdogs, most specific first; each one names what to check.
                new_fault = Fault.NONE
                if stall > stall_max:
                    new_fault = Fault.HOST_STALL
                    reason = (f"host stall: the loop was not scheduled for {1e3 * stall:.0f} ms "
                              f"(limit {1e3 * stall_max:.0f} ms)")
                elif consecutive_transmit_failures >= max_transmit_failures:
                    new_fault = Fault.TRANSMIT_FAILED
                    reason = (f"motor: CAN transmit failed {consecutive_transmit_failures} times in a row "
                              f"({transmit_error})")
                elif unanswered >= motor_min_unanswered and now - oldest_unanswered_s > motor_max_silence:
                    new_fault = Fault.MOTOR_NO_REPLY
                    reason = (f"motor: no valid reply to the last {unanswered} commands "
                              f"(the oldest sent {1e3 * (now - oldest_unanswered_s):.0f} ms ago)")
                    if motor_malformed or getattr(motor, "last_malformed", None):
                        reason += " (malformed frames)"
                elif reply is not None and reply.error_code != 0:
                    new_fault = Fault.MOTOR_ERROR
                    code = reply.error_code
                    reason = f"motor error code {code}: {MotorErrorCode.describe(code)}"
                elif reply is not None and reply.temperature_c > max_temperature:
                    new_fault = Fault.MOTOR_OVER_TEMPERATURE
                    reason = (f"motor temperature {reply.temperature_c:.0f} °C "
                              f"above {max_temperature:.0f} °C")
                elif imu_age > imu_max_age:
                    new_fault = Fault.IMU_STALE
                    reason = (f"IMU: newest sample {1e3 * imu_age:.0f} ms old "
                              f"(limit {1e3 * imu_max_age:.0f} ms)")
                elif not (isfinite(elevation) and isfinite(velocity) and isfinite(motor_velocity)
                          and isfinite(motor_torque)):
                    new_fault = Fault.NONFINITE_INPUT
                    reason = (f"non-finite input: elevation {elevation}, velocity {velocity}, "
                              f"motor velocity {motor_velocity}, motor torque {motor_torque}")
                elif tension > max_tension:
                    new_fault = Fault.TENSION_LIMIT
                    reason = f"load cell: {tension:.1f} N above the {max_tension:.0f} N limit"
                elif cell_problem and stop_on_cell_lost:
                    new_fault, reason = Fault.LOAD_CELL_LOST, f"{cell_problem}: the tension limit is blind"
                elif recording_problem is not None and stop_on_recorder_failure:
                    new_fault, reason = Fault.RECORDER_FAILED, f"recording failed: {recording_problem}"
                elif taking_up and slack is not None and t > slack.timeout_s:
                    new_fault = Fault.SLACK_NOT_TAKEN_UP
                    reason = (f"slack take-up: the cable did not tighten to {slack.pretension_n:g} N in "
                              f"{slack.timeout_s:g} s (pull {slack.pull_n(tension, motor_torque):.1f} N): "
                              "is it attached?")
                elif self._stop_reason is not None:
                    new_fault, reason = Fault.STOP_REQUESTED, self._stop_reason
                elif t >= duration - 1e-9:  # 1 ns: a cycle landing on the end, up to rounding
                    reason = f"duration {duration:g} s reached"
                    new_fault = Fault.NONE
                    state = LoopState.RAMPING_DOWN
                if new_fault != Fault.NONE:
                    fault = new_fault
                    state = LoopState.RAMPING_DOWN
                if state is LoopState.RAMPING_DOWN:
                    stop_time = t
                    ramp_from = torque
                    log = _log.info if fault in (Fault.NONE, Fault.STOP_REQUESTED) else _log.warning
                    log("safe stop at t = %.3f s: %s; ramping %.2f Nm to zero in %.0f ms",
                        t, reason, ramp_from, 1e3 * ramp_s)
            # Degraded states the operator chose to run on in: said once, flagged in every row after.
            if cell_problem and not cell_lost and not stop_on_cell_lost:
                cell_lost = True
                degraded_flags |= int(Fault.LOAD_CELL_LOST)
                degraded.append(f"load cell lost at t = {t:.3f} s ({cell_problem}); tension limit off")
                _log.warning("%s", degraded[-1])
                self._event(t, "degraded", degraded[-1])
            if recording_problem is not None and not recording_lost and not stop_on_recorder_failure:
                recording_lost = True
                degraded_flags |= int(Fault.RECORDER_FAILED)
                degraded.append(f"recording failed at t = {t:.3f} s ({recording_problem}); "
                                "assisting without it")
                _log.error("%s", degraded[-1])

            desired_tension = moment_arm = _NAN
            flags = int(fault) | degraded_flags
            if taking_up and slack is not None and state is LoopState.RUNNING \
                    and slack.pull_n(tension, motor_torque) >= slack.pretension_n:
                taking_up = False
                slack_time = t
                self._event(t, "slack", f"slack taken up in {t:.2f} s "
                            f"({slack.pull_n(tension, motor_torque):.1f} N)")
            if taking_up and state is LoopState.RUNNING:
                # Reeling in: the motor's own velocity loop commands the torque (at most kd·v).
                torque = motor_torque if isfinite(motor_torque) else 0.0
            elif state is LoopState.RUNNING:
                command = controller.step(t, elevation, velocity, motor_velocity, motor_torque)
                torque = command.torque_nm
                desired_tension = command.tension_n
                moment_arm = command.moment_arm_m
                if command.faults:
                    flags |= command.faults
                    controller_fault_cycles += 1
            else:
                torque = ramp_torque_nm(ramp_from, t - stop_time, ramp_s)
                if torque == 0.0 and zero_time != zero_time:
                    zero_time = t

            try:
                if taking_up and state is LoopState.RUNNING and slack is not None and command_mit is not None:
                    new_reply = command_mit(0.0, slack.velocity_rad_s, 0.0, slack.kd_nms_rad)
                else:
                    new_reply = motor.command_torque(torque)
            except TransmitError as error:
                transmit_failures += 1
                consecutive_transmit_failures += 1
                transmit_error = str(error)
            # Any other refusal or a timeout of a motor that waits: no new reply this cycle.
            except DeviceTimeoutError:
                new_reply = None
                consecutive_transmit_failures = 0
            except HardwareError:
                new_reply = None
                motor_malformed = True
                consecutive_transmit_failures = 0
            else:
                consecutive_transmit_failures = 0
            if consecutive_transmit_failures == 0:
                if new_reply is not None:
                    reply = new_reply
                    motor_malformed = False
                    # The command just sent now waits for its own reply.
                    unanswered, oldest_unanswered_s = 1, now
                else:
                    motor_timeouts += 1
                    if unanswered == 0:
                        oldest_unanswered_s = now
                    unanswered += 1
            end = clock.now()

            if record is not None:  # a failed recorder counts what it can no longer write
                record((
                    t,
                    reference(t) if reference is not None else _NAN,
                    elevation,
                    velocity,
                    desired_tension,
                    moment_arm,
                    torque,
                    motor_torque,
                    motor_velocity,
                    tension,
                    int(state),
                    flags,
                ))
            cycles += 1
            timing.record(now - deadline, end > deadline + period)

            if state is LoopState.RAMPING_DOWN and zero_time == zero_time:
                disabled = self._disable_motor()
                safe_time = clock.now() - t0
                state = LoopState.SAFE
                self.state = state
                _log.info("safe state reached at t = %.3f s (motor mode exited)", safe_time)
                break

            # Deadlines are t0 + k·period, computed afresh so that rounding never accumulates.
            k += 1
            deadline = t0 + k * period
            behind = clock.now() - deadline
            if behind > period:
                skipped = int(behind / period)
                k += skipped
                deadline = t0 + k * period
                timing.skip(skipped)

        self.state = state
        return LoopReport(
            reason=reason,
            fault=fault,
            cycles=cycles,
            stop_time_s=stop_time,
            zero_torque_time_s=zero_time,
            safe_time_s=safe_time,
            motor_disabled=disabled,
            timing=timing.summary(),
            motor_timeouts=motor_timeouts,
            controller_fault_cycles=controller_fault_cycles,
            host_stalls=host_stalls,
            worst_host_stall_s=worst_stall,
            transmit_failures=transmit_failures,
            degraded=tuple(degraded),
            slack_take_up_s=slack_time,
        )

    def _disable_motor(self) -> bool:
        try:
            self.motor.disable()
        except HardwareError:
            # Nothing more can be done from here; the reason is in the log and the report.
            _log.exception("could not exit motor mode")
            return False
        return True
