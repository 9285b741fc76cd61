"""The fixed-rate control loop: IMU → controller → motor, with watchdogs and a recorder tap.

Each cycle, on absolute deadlines ``t₀ + k/rate`` of the injected clock (no drift: a late cycle does
not delay the next deadline; when the loop falls behind by whole periods it skips to the next
deadline and counts the skipped cycles as misses):

1. read the latest elevation sample (never blocks) and the latest tension sample, if any;
2. run the watchdogs — IMU older than ``imu_max_age_s``, no valid motor reply for
   ``motor_max_silence_s``, non-finite inputs, a motor error code, over-temperature, tension above
   the limit, a transmit failure, a stop request (SIGINT/SIGTERM) or the end of the run;
3. while running, ``controller.step(...)`` gives the torque; once a watchdog fired, the torque ramps
   to zero over ``ramp_down_s`` and then motor mode is exited (:mod:`bowden.runtime.safety`);
4. send the torque, keep the reply for the next cycle, hand one row to the recorder (non-blocking).

The same loop drives the real suit (AK60 over CAN, NGIMU over UDP, ``MonotonicClock``), the
simulated suit through its wire peers, or the simulated suit directly with its own clock (fast).
The body is plain Python on floats; logging happens only when the state changes.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from bowden.control import Command, Fault
from bowden.errors import (
    DeviceTimeoutError,
    HardwareError,
    MalformedFrameError,
    ParameterError,
    TransmitError,
)
from bowden.hardware.ak60_codec import MotorErrorCode
from bowden.hardware.protocols import Clock, ElevationSensor, Motor, MotorState, TensionSensor
from bowden.runtime.safety import LoopState, SafetyConfig, ramp_torque_nm
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
    """

    rate_hz: float = 500.0
    duration_s: float | None = None
    safety: SafetyConfig = field(default_factory=SafetyConfig)

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
    motor_timeouts: int
    controller_fault_cycles: int

    @property
    def clean(self) -> bool:
        """True when the run ended by its duration or a stop request, not by a watchdog."""
        return self.fault in (Fault.NONE, Fault.STOP_REQUESTED)


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
    ) -> None:
        self.controller = controller
        self.motor = motor
        self.elevation_sensor = elevation_sensor
        self.clock = clock
        self.config = config if config is not None else LoopConfig()
        self.tension_sensor = tension_sensor
        self.record = record
        self.reference_elevation = reference_elevation
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
        try:
            return self._run()
        except BaseException:
            # An error the watchdogs do not cover (a bug, an interrupt mid-cycle): no ramp is possible
            # any more, so at least leave motor mode before the error goes up.
            self._disable_motor()
            raise

    def _run(self) -> LoopReport:
        safety = self.config.safety
        clock = self.clock
        motor = self.motor
        imu = self.elevation_sensor
        load_cell = self.tension_sensor
        controller = self.controller
        record = self.record
        reference = self.reference_elevation
        timing = self.timing
        period = 1.0 / self.config.rate_hz
        duration = self.config.duration_s if self.config.duration_s is not None else math.inf
        imu_max_age = safety.imu_max_age_s
        motor_max_silence = safety.motor_max_silence_s
        max_temperature = safety.max_temperature_c
        max_tension = safety.max_tension_n
        ramp_s = safety.ramp_down_s
        isfinite = math.isfinite
        disabled = False

        reply: MotorState | None = motor.enable()
        t0 = clock.now()
        last_reply_s = t0
        deadline = t0
        k = 0
        state = LoopState.RUNNING
        fault = Fault.NONE
        reason = ""
        stop_time = zero_time = safe_time = _NAN
        ramp_from = 0.0
        torque = 0.0
        motor_timeouts = 0
        controller_fault_cycles = 0
        transmit_failed = False
        motor_malformed = False
        cycles = 0

        while True:
            clock.sleep_until(deadline)
            now = clock.now()
            t = now - t0
            sample = imu.read()
            tension = _NAN
            if load_cell is not None:
                tension_sample = load_cell.read()
                if tension_sample is not None:
                    tension = tension_sample.tension_n
            if sample is not None:
                elevation = sample.elevation_rad
                velocity = sample.elevation_velocity_rad_s
                imu_age = now - sample.time_s
            else:
                elevation = velocity = _NAN
                imu_age = math.inf
            if reply is not None:
                motor_velocity = reply.velocity_rad_s
                motor_torque = reply.torque_nm
            else:
                motor_velocity = motor_torque = _NAN

            if state is LoopState.RUNNING:
                # Watchdogs, most specific first; each one names what to check.
                new_fault = Fault.NONE
                if transmit_failed:
                    new_fault, reason = Fault.TRANSMIT_FAILED, "motor: CAN transmit failed"
                elif now - last_reply_s > motor_max_silence:
                    new_fault = Fault.MOTOR_NO_REPLY
                    reason = f"motor: no valid reply for {1e3 * (now - last_reply_s):.0f} ms"
                    if motor_malformed:
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

            desired_tension = moment_arm = _NAN
            flags = int(fault)
            if state is LoopState.RUNNING:
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
                reply = motor.command_torque(torque)
                last_reply_s = clock.now()
                motor_malformed = False
            # Without a reply the last valid one stands in (its age is the no-reply watchdog's business).
            except DeviceTimeoutError:
                motor_timeouts += 1
            except MalformedFrameError:
                motor_malformed = True
            except TransmitError:
                transmit_failed = True
            except HardwareError:  # any other refusal: treated like a missing reply
                motor_malformed = True
            end = clock.now()

            if record is not None:
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
        )

    def _disable_motor(self) -> bool:
        try:
            self.motor.disable()
        except HardwareError:
            # Nothing more can be done from here; the reason is in the log and the report.
            _log.exception("could not exit motor mode")
            return False
        return True
