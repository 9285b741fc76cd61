"""The identification protocol on a mannequin bench, in a fixed-rate loop over the devices' wires.

Paper, "Data acquisition": the tendon driver unit (TDU, the suit's AK60-6) moves the spool at a
quasi-constant velocity across the arm's range while the mannequin's own motor loads the arm with a
constant torque; the load cell, the IMU on the mannequin's arm and both motors are recorded. Here:

* the TDU tracks a trajectory in MIT mode (``kp``, ``kd`` of the protocol; the target advances at
  the commanded velocity, with trapezoidal ramps at the protocol's acceleration), the mannequin
  motor is commanded in torque (its load ramps when it changes);
* a stroke ends by the IMU: the first visit of a range end (per load and direction) brakes on the
  elevation-per-spool ratio measured so far, aiming short; later ones where the spool stood when the
  arm came to rest there (docs/identification.md, "On your bench");
* every run starts by taking up the cable's slack (:mod:`bowden.runtime.slack`); before each stroke
  the arm is brought to its start if it rests elsewhere (logged, not recorded);
* every cycle is watched, and any fault brings both motors to zero torque and out of motor mode
  within ``ramp_down_s`` plus a cycle: stale IMU, elevation out of the range with its margin, tension
  over the limit, a silent or failing motor, transmit failures, an IMU that does not follow the
  spool, a mannequin that does not hold its load, a load cell that reads nothing while the TDU pulls,
  a stroke that does not end in time.

Strokes are written by :class:`~bowden.runtime.bench_recording.BenchRecordingWriter` as they complete,
so a stop loses at most the stroke under way, and a resumed run skips what is on disk.
"""

from __future__ import annotations

import contextlib
import logging
import math
from collections.abc import Callable

import numpy as np

from bowden.errors import BowdenError, HardwareError, OutputFileError, TransmitError
from bowden.hardware.protocols import MotorState
from bowden.protocol.bench import BenchStroke
from bowden.runtime.bench_config import (
    BenchDevices,
    BenchFault,
    BenchMotor,
    BenchReport,
    BenchRunConfig,
    BenchSafety,
)
from bowden.runtime.bench_recording import LOG_COLUMNS, RECORDING_COLUMNS, BenchRecordingWriter
from bowden.runtime.slack import take_up_slack

_log = logging.getLogger(__name__)

PHASE_HOLD, PHASE_STROKE, PHASE_POSITION, PHASE_TAKE_UP, PHASE_SETTLE = 0, 1, 2, 3, 4
_SETTLE_S = 0.2  # after a stroke, before its end is measured (the arm comes to rest)
_POSITION_ATTEMPTS = 4
_FIRST_SAMPLE_WAIT_S = 0.5
_TAKE_UP_LIFT_RAD = math.radians(3.0)
_MIN_TRAVEL_FOR_RATIO_RAD = 0.3  # spool travel before the elevation/spool ratio is trusted for braking
# Braking starts this much earlier than the stopping distance says: the IMU's sample age, a cycle,
# and the arm's lag behind the spool through the elastic cable (the simulated bench overshot 8° at
# 4 rad/s without it).
_BRAKE_LEAD_S = 0.05
_HOST_STALL_S = 0.01  # a cycle this late is a stall of the host


Progress = Callable[[BenchStroke, int], None]


class BenchRun:
    """Runs the protocol's strokes from ``writer.resume_point`` on, recording each as it completes."""

    def __init__(self, devices: BenchDevices, config: BenchRunConfig, writer: BenchRecordingWriter, *,
                 progress: Progress | None = None) -> None:
        self.devices = devices
        self.config = config
        self.writer = writer
        self.progress = progress
        self.period_s = 1.0 / config.rate_hz
        self.record_every = round(config.rate_hz / config.protocol.sample_rate_hz)
        self.strokes = config.protocol.strokes()
        self._deadline = math.nan
        self._cycle = 0
        self._time_offset_s = 0.0
        self._origin_s = math.nan
        self._rows: list[tuple[float, ...]] = []
        self._log_rows: list[tuple[float, ...]] = []
        self._target_rad = math.nan  # the TDU's position target (multi-turn spool, rad)
        self._velocity_rad_s = 0.0  # the TDU's velocity target
        self._load_command_nm = 0.0
        self._load_from_nm = 0.0
        self._load_to_nm = 0.0
        self._load_ramp_start_s = -math.inf
        self._transmit_failures = 0
        self._tdu_state: MotorState | None = None
        self._mannequin_state: MotorState | None = None
        self._low_load_since = math.nan
        self._deaf_cell_since = math.nan
        self._tension_n = math.nan
        self._elevation_rad = math.nan
        self._stroke: BenchStroke | None = None
        self._phase = PHASE_HOLD
        # (range end, load, direction of arrival) → (elevation, spool) with the arm at rest there: the
        # cable's stretch and the sheath's friction differ with both.
        self._ends: dict[tuple[float, float, float], tuple[float, float]] = {}
        self._stall_end_s = -math.inf  # when the last host stall ended (clock time)

    # --- the run ---------------------------------------------------------------------------------
    def run(self) -> BenchReport:
        """Enable both motors, take up the slack, run the remaining strokes, leave both safe.

        A fault brings both motors to the safe state and is reported (never raised); a device that
        does not answer when enabled raises :class:`~bowden.errors.HardwareError` with nothing enabled.
        """
        done = self.writer.resume_point.strokes_done
        report = BenchReport(strokes_done=done, strokes_total=len(self.strokes))
        self._time_offset_s = self.writer.resume_point.last_time_s + (1.0 if done else 0.0)
        self._enable()
        try:
            self._start_clock()
            self._take_up_slack()
            for stroke in self.strokes[done:]:
                self._stroke = stroke
                self._rows, self._log_rows = [], []
                self._position_for(stroke)
                self._hold(stroke)
                self._run_stroke(stroke)
                try:
                    self.writer.write_stroke(np.array(self._rows), np.array(self._log_rows), stroke.index + 1)
                except OutputFileError as error:  # a full disk: stop safely, the strokes before stay
                    raise BenchFault(f"recording failed: {error}") from None
                report.strokes_done = stroke.index + 1
                if self.progress is not None:
                    self.progress(stroke, len(self.strokes))
            self._stroke = None
            self._finish_load()
        except BenchFault as fault:
            report.fault = str(fault)
            report.fault_at_s = self.devices.clock.now()
            report.safe_at_s = self._safe_stop(report.exit_errors)
            self._keep_partial_log()
            return report
        except BaseException as error:  # a bug, Ctrl-C, a full disk: the motors first
            report.safe_at_s = self._safe_stop(report.exit_errors)
            self._keep_partial_log()
            if isinstance(error, KeyboardInterrupt):
                report.fault = "interrupted"
                return report
            raise
        report.safe_at_s = self._safe_stop(report.exit_errors)
        return report

    def _keep_partial_log(self) -> None:
        """The device log of the stroke under way when the run stopped (the stroke is not recorded)."""
        rows, self._log_rows = self._log_rows, []
        if rows:
            try:
                self.writer.write_log(np.array(rows))
            except BowdenError as error:
                _log.error("bench: %s", error)

    def _enable(self) -> None:
        tdu, mannequin = self.devices.tdu, self.devices.mannequin
        try:
            self._mannequin_state = mannequin.enable()
        except HardwareError as error:
            raise HardwareError(f"the mannequin's motor does not answer: {error}") from None
        try:
            self._mannequin_state = mannequin.command_torque(0.0) or self._mannequin_state
            self._tdu_state = tdu.enable()
        except HardwareError as error:
            _quietly(mannequin.disable)
            raise HardwareError(f"the TDU's motor does not answer: {error}") from None
        self._target_rad = self._tdu_state.position_rad

    def _start_clock(self) -> None:
        clock = self.devices.clock
        now = clock.now()
        waited_until = now + _FIRST_SAMPLE_WAIT_S
        while self.devices.imu.read() is None:  # the first sample after the calibration
            if clock.now() > waited_until:
                raise BenchFault(f"no IMU sample within {_FIRST_SAMPLE_WAIT_S:g} s of enabling the motors")
            clock.sleep_until(clock.now() + 0.001)
        now = clock.now()
        self._origin_s = now
        self._deadline = now

    # --- phases ----------------------------------------------------------------------------------
    def _take_up_slack(self) -> None:
        self._phase = PHASE_TAKE_UP
        slack = self.config.slack

        start_elevation = math.nan

        def cycle(velocity_rad_s: float, kd: float) -> float:
            nonlocal start_elevation
            self._cycle_once(velocity_rad_s=velocity_rad_s, kp=0.0, kd=kd)
            if math.isnan(start_elevation):
                start_elevation = self._elevation_rad
            if self._elevation_rad - start_elevation > _TAKE_UP_LIFT_RAD:
                # The cable is taut and lifts the arm: near the top of the range a light load balances
                # less than the pretension.
                return math.inf
            return self._tension_n

        # The mannequin holds the arm against the cable as it tightens, with the next stroke's load if
        # larger (a light load at the top of the range balances less than the pretension).
        upcoming = self.strokes[self.writer.resume_point.strokes_done:]
        self._set_load(max([self.config.take_up_load_nm] + [s.load_nm for s in upcoming[:1]]))
        take_up_slack(slack, cycle, period_s=self.period_s, fail=BenchFault)
        state = self._tdu_state
        self._target_rad = state.position_rad if state is not None else self._target_rad
        self._velocity_rad_s = 0.0

    def _position_for(self, stroke: BenchStroke) -> None:
        """Bring the arm to the start of ``stroke`` (logged, not recorded) if it is not there."""
        p = self.config.protocol
        start = p.low_rad if stroke.raising else p.high_rad
        self._set_load(stroke.load_nm)
        self._dwell(self.config.load_ramp_s, PHASE_POSITION)  # the new load settles first
        tolerance = self.config.safety.range_margin_rad / 2.0
        speed = self.config.position_speed_rad_s
        for _ in range(_POSITION_ATTEMPTS):  # the arm may settle past the mark (sheath, stretch)
            if abs(self._elevation_rad - start) <= tolerance:
                return
            direction = 1.0 if start > self._elevation_rad else -1.0
            self._move(direction * speed, start, PHASE_POSITION)
            self._dwell(_SETTLE_S, PHASE_POSITION)
            speed /= 2.0
        raise BenchFault(f"the arm could not be brought to {math.degrees(start):.0f}° for the next stroke "
                         f"(it rests at {math.degrees(self._elevation_rad):.1f}°)")

    def _hold(self, stroke: BenchStroke) -> None:
        self._set_load(stroke.load_nm)
        self._dwell(self.config.protocol.hold_s, PHASE_HOLD)

    def _run_stroke(self, stroke: BenchStroke) -> None:
        p = self.config.protocol
        end = p.high_rad if stroke.raising else p.low_rad
        self._move(stroke.spool_velocity_rad_s, end, PHASE_STROKE)
        self._dwell(0.0, PHASE_HOLD)  # one cycle at rest ends the stroke's record
        self._dwell(_SETTLE_S, PHASE_SETTLE)  # logged, not recorded: the next stroke's hold follows
        self._remember_end(end, 1.0 if stroke.raising else -1.0)

    def _remember_end(self, end_rad: float, direction: float) -> None:
        """Where the spool stands with the arm at rest at ``end_rad``'s end of the range, reached by
        a stroke in ``direction`` (the sheath's friction makes the cable's stretch depend on it)."""
        if abs(self._elevation_rad - end_rad) <= self.config.safety.range_margin_rad:
            self._ends[(end_rad, self._load_to_nm, direction)] = (self._elevation_rad, self._spool_position())

    def _spool_stop(self, stop_rad: float, direction: float) -> float | None:
        """The spool position that puts the arm at ``stop_rad``, from where it rested there after a
        stroke in ``direction`` under this load (corrected by the elevation-per-spool ratio of the
        range once both ends are known); None before."""
        load = self._load_to_nm
        end = self._ends.get((stop_rad, load, direction))
        if end is None:
            return None
        elevation, spool = end
        ends = [value for (_, end_load, _), value in self._ends.items() if end_load == load]
        if len(ends) == 2:
            (e1, q1), (e2, q2) = ends
            if abs(q2 - q1) > _MIN_TRAVEL_FOR_RATIO_RAD and abs(e2 - e1) > 0.0:
                spool += (stop_rad - elevation) * (q2 - q1) / (e2 - e1)
        return spool

    def _finish_load(self) -> None:
        self._set_load(0.0)
        self._dwell(self.config.load_ramp_s, PHASE_HOLD)

    def _dwell(self, duration_s: float, phase: int) -> None:
        self._phase = phase
        self._velocity_rad_s = 0.0
        end = self._deadline + duration_s
        while True:
            self._cycle_once()
            if self._deadline >= end:
                return

    def _move(self, velocity_rad_s: float, stop_rad: float, phase: int) -> None:
        """Spool at ``velocity_rad_s`` (trapezoidal) until the arm stops at ``stop_rad``."""
        p, safety = self.config.protocol, self.config.safety
        self._phase = phase
        direction = 1.0 if velocity_rad_s > 0.0 else -1.0
        speed = abs(velocity_rad_s)
        step = p.spool_acceleration_rad_s2 * self.period_s
        start_spool = self._spool_position()
        start_elevation = self._elevation_rad
        span = abs(stop_rad - start_elevation)
        expected_s = 2.0 * span / (0.5 * speed) + speed / p.spool_acceleration_rad_s2
        timeout_s = self.config.stroke_timeout_factor * expected_s + 2.0
        started = self._deadline
        braking = False
        while True:
            travelled = self._spool_position() - start_spool
            moved = self._elevation_rad - start_elevation
            if abs(travelled) >= safety.imu_follow_spool_rad and abs(moved) < safety.imu_follow_min_rad:
                raise BenchFault(f"the IMU does not follow the arm: the spool turned {abs(travelled):.1f} "
                                 f"rad but the elevation changed {math.degrees(abs(moved)):.1f}° "
                                 "(is it on the arm?)")
            if not braking:
                v = abs(self._velocity_rad_s)
                stopping_spool = v * v / (2.0 * p.spool_acceleration_rad_s2) + v * _BRAKE_LEAD_S
                # (A positioning move goes by the elevation: it starts from wherever the arm rests.)
                spool_stop = self._spool_stop(stop_rad, direction) if phase == PHASE_STROKE else None
                if spool_stop is not None:
                    # The spool position at which the arm rested at this end before (through the
                    # taut cable): brake so that the spool itself stops there.
                    braking = direction * (spool_stop - self._spool_position()) <= stopping_spool
                else:
                    # First visit of this end (or a positioning move): the elevation/spool ratio of
                    # the move so far. A stroke aims half the range margin short, as the arm lags the
                    # spool through the sheath and catches up when it stops (10° past the end
                    # measured); a positioning move is slow and tries again if it misses.
                    ratio = moved / travelled if abs(travelled) >= _MIN_TRAVEL_FOR_RATIO_RAD else 0.0
                    short = safety.range_margin_rad / 2.0 if phase == PHASE_STROKE else 0.0
                    remaining = direction * (stop_rad - self._elevation_rad) - short
                    braking = remaining <= abs(ratio) * stopping_spool
            if braking:
                self._velocity_rad_s = direction * max(abs(self._velocity_rad_s) - step, 0.0)
                if self._velocity_rad_s == 0.0:
                    return
            else:
                self._velocity_rad_s = direction * min(abs(self._velocity_rad_s) + step, speed)
            if self._deadline - started > timeout_s:
                raise BenchFault(f"the arm did not reach {math.degrees(stop_rad):.0f}° within "
                                 f"{timeout_s:.1f} s "
                                 f"(at {math.degrees(self._elevation_rad):.1f}°)")
            self._cycle_once()

    # --- one cycle -------------------------------------------------------------------------------
    def _cycle_once(self, *, velocity_rad_s: float | None = None, kp: float | None = None,
                    kd: float | None = None) -> None:
        clock = self.devices.clock
        self._deadline += self.period_s
        clock.sleep_until(self._deadline)
        now = clock.now()
        if now - self._deadline > _HOST_STALL_S:
            # The host stalled (a stroke's fsync, the scheduler): no burst of catch-up cycles, and
            # replies missing across the stall are not the motors' fault.
            self._deadline = now
            self._stall_end_s = now
        self._sense(now)
        p = self.config.protocol
        velocity = self._velocity_rad_s if velocity_rad_s is None else velocity_rad_s
        self._target_rad += velocity * self.period_s
        self._load_command_nm = self._load_now(now)
        try:
            state = self.devices.mannequin.command_torque(self._load_command_nm)
            self._mannequin_state = state or self._mannequin_state
            if kp is not None and kp == 0.0:
                state = self.devices.tdu.command_mit(0.0, velocity, 0.0, kd or 0.0)
            else:
                state = self.devices.tdu.command_mit(self._target_rad, velocity, p.position_gain_nm_rad,
                                                     p.velocity_gain_nms_rad)
            self._tdu_state = state or self._tdu_state
            self._transmit_failures = 0
        except TransmitError as error:
            self._transmit_failures += 1
            if self._transmit_failures >= self.config.safety.max_transmit_failures:
                raise BenchFault(f"CAN transmit failed {self._transmit_failures} times in a row: "
                                 f"{error}") from None
        if kp is not None and kp == 0.0 and self._tdu_state is not None:
            self._target_rad = self._tdu_state.position_rad  # velocity mode: the target follows
        self._check_motors(now)
        self._record(now, velocity)
        self._cycle += 1

    def _sense(self, now: float) -> None:
        safety, p = self.config.safety, self.config.protocol
        sample = self.devices.imu.read()
        # As the loop does: after a stall of the host, ages count from its end (the bench could not
        # read during it), so a paused host never reads as a stale IMU.
        if sample is None or now - max(sample.time_s, self._stall_end_s) > safety.imu_max_age_s:
            age = "no sample" if sample is None else f"{1e3 * (now - sample.time_s):.0f} ms old"
            raise BenchFault(f"IMU stale ({age}, limit {1e3 * safety.imu_max_age_s:.0f} ms)")
        if not math.isfinite(sample.elevation_rad):
            raise BenchFault("IMU sent a non-finite elevation")
        self._elevation_rad = sample.elevation_rad
        low, high = p.low_rad - safety.range_margin_rad, p.high_rad + safety.range_margin_rad
        if self._phase in (PHASE_TAKE_UP, PHASE_POSITION):
            low = -math.pi  # the arm may hang below the range until it is brought to a stroke's start
        if not low <= sample.elevation_rad <= high:
            raise BenchFault(f"elevation {math.degrees(sample.elevation_rad):.1f}° left the bench's range "
                             f"({math.degrees(low):.0f}°–{math.degrees(high):.0f}°)")
        cell = self.devices.load_cell
        failure = getattr(cell, "failure", None)
        if failure is not None:
            raise BenchFault(f"load cell lost: {failure}")
        reading = cell.read()
        if reading is None or now - reading.time_s > 0.25:
            raise BenchFault("load cell: no reading for 250 ms")
        self._tension_n = reading.tension_n
        if reading.tension_n > safety.max_tension_n:
            raise BenchFault(f"tension {reading.tension_n:.0f} N over the limit "
                             f"({safety.max_tension_n:.0f} N)")
        pull = self._pull_n()
        if pull > safety.load_cell_check_pull_n and reading.tension_n < safety.load_cell_min_n:
            if math.isnan(self._deaf_cell_since):
                self._deaf_cell_since = now
            elif now - self._deaf_cell_since > safety.load_cell_window_s:
                raise BenchFault(f"the load cell reads {reading.tension_n:.1f} N while the TDU pulls about "
                                 f"{pull:.0f} N: check its wiring and calibration")
        else:
            self._deaf_cell_since = math.nan

    def _check_motors(self, now: float) -> None:
        safety = self.config.safety
        for name, motor, state in (("TDU", self.devices.tdu, self._tdu_state),
                                   ("mannequin motor", self.devices.mannequin, self._mannequin_state)):
            unanswered = motor.unanswered_commands
            silent_s = now - max(motor.oldest_unanswered_send_s, self._stall_end_s)
            if unanswered >= safety.motor_min_unanswered and silent_s > safety.motor_max_silence_s:
                raise BenchFault(f"{name}: no reply to {unanswered} commands in {1e3 * silent_s:.0f} ms")
            if state is not None and state.error_code:
                raise BenchFault(f"{name} reports error code {state.error_code}")
            if state is not None and state.temperature_c > safety.max_temperature_c:
                raise BenchFault(f"{name} at {state.temperature_c:.0f} °C "
                                 f"(limit {safety.max_temperature_c:.0f})")
        command = self._load_command_nm
        held = self._mannequin_state.torque_nm if self._mannequin_state is not None else 0.0
        ramping = now - self._load_ramp_start_s < self.config.load_ramp_s + safety.load_hold_window_s
        if command > 0.2 and not ramping and held < safety.load_hold_fraction * command:
            if math.isnan(self._low_load_since):
                self._low_load_since = now
            elif now - self._low_load_since > safety.load_hold_window_s:
                raise BenchFault(f"the mannequin's motor does not hold its load: {held:.2f} Nm of "
                                 f"{command:.2f} Nm commanded")
        else:
            self._low_load_since = math.nan

    def _record(self, now: float, velocity: float) -> None:
        if self._cycle % self.record_every:
            return
        t = now - self._origin_s + self._time_offset_s
        tdu, man = self._tdu_state, self._mannequin_state
        trial = self._stroke.index if self._stroke is not None else -1
        nan = math.nan
        if self._phase in (PHASE_HOLD, PHASE_STROKE) and self._stroke is not None and tdu is not None:
            self._rows.append((t, tdu.torque_nm, tdu.velocity_rad_s, self._tension_n, self._elevation_rad,
                               trial))
        self._log_rows.append((
            t, trial, self._phase, self._target_rad, velocity, tdu.position_rad if tdu else nan,
            self._load_command_nm, man.torque_nm if man else nan, man.position_rad if man else nan,
            man.velocity_rad_s if man else nan,
        ))

    # --- helpers ---------------------------------------------------------------------------------
    def _set_load(self, load_nm: float) -> None:
        if load_nm == self._load_to_nm:
            return
        self._load_from_nm = self._load_command_nm
        self._load_to_nm = load_nm
        self._load_ramp_start_s = self.devices.clock.now()

    def _load_now(self, now: float) -> float:
        fraction = min(max((now - self._load_ramp_start_s) / self.config.load_ramp_s, 0.0), 1.0)
        return self._load_from_nm + fraction * (self._load_to_nm - self._load_from_nm)

    def _spool_position(self) -> float:
        return self._tdu_state.position_rad if self._tdu_state is not None else 0.0

    def _pull_n(self) -> float:
        """The TDU's pull on the cable estimated from its torque (N), for checks without the load cell."""
        torque = self._tdu_state.torque_nm if self._tdu_state is not None else 0.0
        return torque / self.config.spool_radius_m

    def _safe_stop(self, errors: list[str]) -> float:
        """Ramp both torques to zero over ``ramp_down_s``, then leave motor mode; the clock time after."""
        clock, tdu, mannequin = self.devices.clock, self.devices.tdu, self.devices.mannequin
        ramp = self.config.safety.ramp_down_s
        tdu_from = self._tdu_state.torque_nm if self._tdu_state is not None else 0.0
        load_from = self._load_command_nm
        start = clock.now()
        deadline = start
        while True:
            deadline += self.period_s
            fraction = max(1.0 - (deadline - start) / ramp, 0.0)
            for motor, torque in ((tdu, tdu_from * fraction), (mannequin, load_from * fraction)):
                with contextlib.suppress(HardwareError, OSError):  # the exit frame below is what matters
                    motor.command_torque(torque)
            if fraction == 0.0:
                break
            clock.sleep_until(deadline)
        # Every exit frame goes out before any reply is waited for: a silent motor delays no other.
        sent = []
        for name, motor in (("TDU", tdu), ("mannequin motor", mannequin)):
            try:
                motor.request_exit()
                sent.append(motor)
            except (HardwareError, OSError) as error:
                errors.append(f"{name}: could not leave motor mode: {error}")
        # A motor that did not answer may not have heard its exit (a frame lost on the bus): once more.
        unconfirmed = [motor for motor in sent if not motor.await_exit()]
        for motor in unconfirmed:
            with contextlib.suppress(HardwareError, OSError):
                motor.request_exit()
        for motor in unconfirmed:
            motor.await_exit()
        return clock.now()


def _quietly(action: Callable[[], None]) -> None:
    try:
        action()
    except (HardwareError, OSError) as error:
        _log.warning("bench: %s", error)


__all__ = [
    "LOG_COLUMNS", "RECORDING_COLUMNS", "BenchDevices", "BenchFault", "BenchMotor", "BenchReport",
    "BenchRun", "BenchRunConfig", "BenchSafety",
]
