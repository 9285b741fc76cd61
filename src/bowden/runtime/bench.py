"""The identification protocol on a mannequin bench, in a fixed-rate loop over the devices' wires.

Paper, "Data acquisition": the tendon driver unit (TDU, the suit's AK60-6) moves the spool at a
quasi-constant velocity across the arm's range while the mannequin's own motor loads the arm with a
constant torque; the load cell, the IMU on the mannequin's arm and both motors are recorded. Here:

* the TDU tracks a trajectory in MIT mode (``kp``, ``kd`` of the protocol; the target advances at
  the commanded velocity by the clock, with trapezoidal ramps at the protocol's acceleration), the
  mannequin motor is commanded in torque (its load ramps when it changes);
* a stroke brakes where the spool stood when the arm last came to rest at its end under the same
  load, arriving the same way (:mod:`bowden.runtime.bench_ends`, journalled for a resume); a slow
  stroke to an end not visited yet brakes on the elevation-per-spool ratio measured so far, aiming
  short; a faster one is preceded by a slow, unrecorded move to that end and back to learn it. A
  stroke is recorded until the arm rests; one that rests short of its end is run again (three
  attempts, then a fault that says so) (docs/identification.md, "On your bench");
* the mannequin's motor brakes an arm flung beyond the range with soft walls on its load
  (:mod:`bowden.runtime.bench_walls`);
* every run starts by taking up the cable's slack (:mod:`bowden.runtime.slack`); before each stroke
  the TDU servoes the arm to the stroke's start on the IMU and holds it there while the mannequin's
  load ramps to the stroke's, until the arm rests there (logged, not recorded);
* every cycle is watched, and any fault brings both motors to zero torque and out of motor mode
  within ``ramp_down_s`` plus a cycle: stale IMU, elevation out of the range with its margin, tension
  over the limit, a silent or failing motor, transmit failures, an IMU that does not follow the
  spool, a mannequin that does not hold its load, a load cell that reads nothing while the TDU pulls
  or while the arm rests on the cable under its load, an arm that cannot be held at a stroke's start
  under its load, a stroke that does not end in time or does not reach its end. A load cell whose
  reader the host starves is a gap in the data, not a fault (:mod:`bowden.runtime.bench_cell`):
  the stroke recorded with it is run again.

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
from bowden.runtime.bench_cell import LoadCellWatch
from bowden.runtime.bench_config import (
    BenchDevices,
    BenchFault,
    BenchMotor,
    BenchReport,
    BenchRunConfig,
    BenchSafety,
)
from bowden.runtime.bench_ends import LearnedEnds
from bowden.runtime.bench_recording import LOG_COLUMNS, RECORDING_COLUMNS, BenchRecordingWriter
from bowden.runtime.bench_walls import JointReference, SoftWalls
from bowden.runtime.slack import take_up_slack

_log = logging.getLogger(__name__)

PHASE_HOLD, PHASE_STROKE, PHASE_POSITION, PHASE_TAKE_UP, PHASE_SETTLE = 0, 1, 2, 3, 4
_FIRST_SAMPLE_WAIT_S = 0.5
_STROKE_ATTEMPTS = 3  # a stroke that rests short of its end is run again, learning where it rested
_GAP_RETRIES = 3  # a stroke recorded with a gap in the load cell's data is run again this often
# The arm is at rest when its elevation's speed stays below _REST_SPEED_RAD_S for _REST_WINDOW_S: the
# speed is the difference of two running means of the IMU's elevation (time constants _REST_FAST_S
# and _REST_SLOW_S) over the difference of their lags. (Not the gyroscope: with the arm hanging
# near 0° the elevation's rate is ill-conditioned.)
_REST_SPEED_RAD_S = math.radians(5.0)
_REST_FAST_S = 0.03
_REST_SLOW_S = 0.15
_REST_WINDOW_S = 0.1
_STROKE_REST_LIMIT_S = 4.0  # how long a stroke's record waits for the arm to come to rest
# Servoing the arm to a stroke's start: the spool's speed is this gain times the elevation error,
# through the cuff's spool-per-elevation ratio (a first-order approach with a 0.25 s time constant,
# slow against the cable and the arm); it lets go within _SERVO_DEADBAND_RAD and takes hold again
# beyond _SERVO_ENGAGE_RAD (the IMU's noise, 0.3° on the simulated bench, would keep it hunting).
_SERVO_GAIN_1_S = 4.0
_SERVO_DEADBAND_RAD = math.radians(0.5)
_SERVO_ENGAGE_RAD = math.radians(2.0)
_SERVO_EXTRA_S = 6.0  # beyond the travel at the positioning speed and the load's ramp
_POSITION_STEPS = 6  # moves by the geometry, each from the arm at rest
_IMU_JOINT_WINDOW_S = 0.5  # the IMU apart from the still joint this long, between positioning steps
_TAKE_UP_LIFT_RAD = math.radians(3.0)
_MIN_TRAVEL_FOR_RATIO_RAD = 0.3  # spool travel before the elevation/spool ratio is trusted for braking
# Braking starts this much earlier than the stopping distance says: the IMU's sample age, a cycle,
# and the arm's lag behind the spool through the elastic cable (the simulated bench overshot 8° at
# 4 rad/s without it).
_BRAKE_LEAD_S = 0.05
_HOST_STALL_S = 0.01  # a cycle this late is a stall of the host
# The spool target advances by the clock, but by at most this much time per cycle: after a stall of
# the host the motor held its last target, and a jump of the whole stall would jerk the cable.
_MAX_ADVANCE_S = _HOST_STALL_S
_TAKE_UP_STALL_S = 0.5  # a stalled spool pulling this long with a silent load cell: the load cell


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
        self._load_command_nm = 0.0  # the load (ramped), without the wall's
        self._mannequin_command_nm = 0.0  # what the mannequin's motor is told: the load and the wall
        margin = config.safety.range_margin_rad / 2.0
        self._walls = SoftWalls(config.protocol.low_rad - margin, config.protocol.high_rad + margin,
                                config.wall_stiffness_nm_rad, config.wall_damping_nms_rad)
        self._joint = JointReference()  # the mannequin's joint angle against the IMU's elevation
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
        self._ends = LearnedEnds(config.geometry, config.spool_radius_m, writer.resume_point.learned)
        self._stall_end_s = -math.inf  # when the last host stall ended (clock time)
        self._last_cycle_s = math.nan  # clock time of the last cycle (the target advances by the clock)
        self._cycle_dt_s = self.period_s
        self._arrival = 0.0  # the direction the spool last moved in (±1): the friction's branch
        self._rest_speed_rad_s = math.inf  # the elevation's speed, from two running means
        self._fast_mean_rad = self._slow_mean_rad = math.nan
        self._rest_since = math.nan
        self.scouting_moves = 0  # slow moves to learn an end before a fast stroke
        self._furthest_rad = math.nan  # the furthest elevation of the stroke under way
        self._cell_watch = LoadCellWatch(config.safety.load_cell_max_age_s,
                                         config.safety.load_cell_reader_max_idle_s)
        self._gap_in_attempt = False  # the load cell's reader starved while this attempt was recorded

    @property
    def phase(self) -> int:
        """What the bench does now (``PHASE_*``; the device log's ``phase``)."""
        return self._phase

    @property
    def stroke_under_way(self) -> BenchStroke | None:
        """The stroke being run (its positioning and hold included), None between runs."""
        return self._stroke

    # --- the run ---------------------------------------------------------------------------------
    def run(self) -> BenchReport:
        """Enable both motors, take up the slack, run the remaining strokes, leave both safe.

        A fault brings both motors to the safe state and is reported (never raised); a device that
        does not answer when enabled raises :class:`~bowden.errors.HardwareError` with nothing enabled.
        """
        done = self.writer.resume_point.strokes_done
        report = BenchReport(strokes_done=done, strokes_total=len(self.strokes))
        # Times continue a second after everything written before (the device log included).
        last = self.writer.resume_point.last_time_s
        self._time_offset_s = last + (1.0 if last > 0.0 else 0.0)
        self._enable()
        try:
            self._start_clock()
            self._take_up_slack()
            for stroke in self.strokes[done:]:
                self._stroke = stroke
                self._log_rows = []
                self._run_covering(stroke)
                try:
                    self.writer.write_stroke(np.array(self._rows), np.array(self._log_rows), stroke.index + 1,
                                             learned=self._ends.to_json())
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
            report.data_gaps = self._cell_watch.gaps
            self._keep_partial_log()
            return report
        except BaseException as error:  # a bug, Ctrl-C, a full disk: the motors first
            report.safe_at_s = self._safe_stop(report.exit_errors)
            report.data_gaps = self._cell_watch.gaps
            self._keep_partial_log()
            if isinstance(error, KeyboardInterrupt):
                report.fault = "interrupted"
                return report
            raise
        report.safe_at_s = self._safe_stop(report.exit_errors)
        report.data_gaps = self._cell_watch.gaps
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
        self._last_cycle_s = now
        self._stall_end_s = now  # sample ages count from here at most: nothing was read before

    # --- phases ----------------------------------------------------------------------------------
    def _take_up_slack(self) -> None:
        self._phase = PHASE_TAKE_UP
        slack = self.config.slack

        start_elevation = math.nan
        stalled_since = math.nan

        def cycle(velocity_rad_s: float, kd: float) -> float:
            nonlocal start_elevation, stalled_since
            self._cycle_once(velocity_rad_s=velocity_rad_s, kp=0.0, kd=kd)
            if math.isnan(start_elevation):
                start_elevation = self._elevation_rad
            if self._elevation_rad - start_elevation > _TAKE_UP_LIFT_RAD:
                # The cable is taut and lifts the arm: near the top of the range a light load balances
                # less than the pretension.
                return math.inf
            stalled_since = self._check_take_up_cell(velocity_rad_s, stalled_since)
            return self._tension_n

        # The mannequin holds the arm lightly against the cable as it tightens: a heavy load would pull
        # it to the bottom of its travel, where the cable's lever is too short to lift it again; the
        # stroke's load ramps in later, with the arm held at the stroke's start.
        self._set_load(self.config.take_up_load_nm)
        take_up_slack(slack, cycle, period_s=self.period_s, fail=BenchFault)
        self._arrival = 1.0
        state = self._tdu_state
        self._target_rad = state.position_rad if state is not None else self._target_rad
        self._velocity_rad_s = 0.0

    def _run_covering(self, stroke: BenchStroke) -> None:
        """Run ``stroke`` until it covers the range (its rows in ``self._rows``), or fault saying so."""
        p = self.config.protocol
        end = p.high_rad if stroke.raising else p.low_rad
        short = gaps = 0
        while short < _STROKE_ATTEMPTS:
            self._rows = []
            self._position_for(stroke)
            self._gap_in_attempt = False
            self._dwell(p.hold_s, PHASE_HOLD)
            covered = self._run_stroke(stroke)
            if self._gap_in_attempt:
                gaps += 1
                if gaps > _GAP_RETRIES:
                    raise BenchFault(f"stroke {stroke.index + 1}: the load cell's reader was starved in "
                                     f"{gaps} attempts in a row: the host is too busy")
                _log.warning("bench: stroke %d is run again (a gap in the load cell's data)",
                             stroke.index + 1)
                continue
            if covered:
                return
            short += 1
        raise BenchFault(f"stroke {stroke.index + 1} ({stroke.spool_velocity_rad_s:+g} rad/s, load "
                         f"{stroke.load_nm:g} Nm) came to rest at {math.degrees(self._elevation_rad):.1f}°, "
                         f"short of {math.degrees(end):.0f}°, in {_STROKE_ATTEMPTS} attempts: the arm does "
                         "not follow the spool at this speed and load")

    def _position_for(self, stroke: BenchStroke) -> None:
        """Hold the arm at the start of ``stroke`` while its load ramps in (logged, not recorded); a
        fast stroke to an end not yet learned under this load is preceded by a slow move there."""
        p = self.config.protocol
        start, end = (p.low_rad, p.high_rad) if stroke.raising else (p.high_rad, p.low_rad)
        direction = 1.0 if stroke.raising else -1.0
        # The new load ramps in with the arm held at the start (resting there anchors what an earlier
        # run learned: bench_ends). A raising stroke may start from below its start: near the low end
        # a heavy load has no stable rest for the arm (on the simulated bench 4 Nm flips it between
        # 0° and 35° at 20°), and an arm hanging lower is safe; the stroke covers the range anyway.
        self._set_load(stroke.load_nm)
        self._servo_to(start, or_below=stroke.raising)
        fast = abs(stroke.spool_velocity_rad_s) > self.config.position_speed_rad_s
        if fast and self._ends.stop((end, stroke.load_nm, direction)) is None:
            # The first stroke to this end under this load is too fast to brake on the ratio seen
            # on the way (the arm lags the spool and catches up past the end): learn the end first.
            self._servo_to(end)
            self._servo_to(start, or_below=stroke.raising)
            self.scouting_moves += 1

    def _servo_to(self, target_rad: float, *, or_below: bool = False) -> None:
        """Bring the arm to rest within half the range margin of ``target_rad`` with the mannequin's
        load ramped in (logged, not recorded); the rest is learned if it is a range end.

        While the load ramps, the spool servoes the arm on the IMU towards the target, holding it
        against the changing load (a heavy load would otherwise pull it down to where the cable's
        lever is too short to lift it again). Then it goes in steps: the arm comes to rest, and the
        spool moves by what the cuff's geometry says the remaining error takes (a continuous servo
        hunts under a heavy load: the sheath's friction sticks and slips). ``or_below``: a rest below
        the target is as good (the low end of a raising stroke)."""
        p, safety = self.config.protocol, self.config.safety
        self._phase = PHASE_POSITION
        speed = self.config.position_speed_rad_s
        travel_s = abs(self._spool_travel(self._elevation_rad, target_rad)) / speed
        deadline = self._deadline + travel_s + self.config.load_ramp_s + _SERVO_EXTRA_S
        engaged = True
        while self.devices.clock.now() - self._load_ramp_start_s < self.config.load_ramp_s:
            error = target_rad - self._elevation_rad
            engaged = abs(error) > (_SERVO_DEADBAND_RAD if engaged else _SERVO_ENGAGE_RAD)
            wanted = 0.0
            if engaged:
                wanted = _SERVO_GAIN_1_S * error * self._spool_per_elevation(self._elevation_rad)
                wanted = min(max(wanted, -speed), speed)
            step = p.spool_acceleration_rad_s2 * self._cycle_dt_s
            self._velocity_rad_s += min(max(wanted - self._velocity_rad_s, -step), step)
            self._cycle_once()
            self._check_position_deadline(target_rad, deadline)
        for _ in range(_POSITION_STEPS):
            self._come_to_rest(target_rad, deadline)
            self._check_imu_against_joint(target_rad, deadline)
            error = target_rad - self._elevation_rad
            if abs(error) <= safety.range_margin_rad / 2.0 or (or_below and error > 0.0):
                self._learn_rest()
                return
            self._spool_move(self._spool_travel(self._elevation_rad, target_rad), target_rad, deadline)
        self._check_position_deadline(target_rad, -math.inf)

    def _spool_travel(self, from_rad: float, to_rad: float) -> float:
        """The spool's travel (rad, > 0 reeling in) that moves the arm between two elevations by the
        cuff's geometry (the cable's stretch aside)."""
        length = self.config.geometry.cable_length_m
        return (length(from_rad) - length(to_rad)) / self.config.spool_radius_m

    def _spool_move(self, travel_rad: float, target_rad: float, deadline: float) -> None:
        """Move the spool's target by ``travel_rad`` (trapezoidal, at most the positioning speed)."""
        p = self.config.protocol
        goal = self._target_rad + travel_rad
        direction = 1.0 if travel_rad > 0.0 else -1.0
        while True:
            remaining = direction * (goal - self._target_rad)
            v = abs(self._velocity_rad_s)
            step = p.spool_acceleration_rad_s2 * self._cycle_dt_s
            if remaining <= v * v / (2.0 * p.spool_acceleration_rad_s2) + v * self._cycle_dt_s:
                v = max(v - step, 0.0)
                if v == 0.0:
                    self._velocity_rad_s = 0.0
                    return
            else:
                v = min(v + step, self.config.position_speed_rad_s)
            self._velocity_rad_s = direction * v
            self._cycle_once()
            self._check_position_deadline(target_rad, deadline)

    def _come_to_rest(self, target_rad: float, deadline: float) -> None:
        """Stop the spool and wait until the arm rests."""
        step = self.config.protocol.spool_acceleration_rad_s2
        while self._velocity_rad_s != 0.0:
            v = max(abs(self._velocity_rad_s) - step * self._cycle_dt_s, 0.0)
            self._velocity_rad_s = math.copysign(v, self._velocity_rad_s)
            self._cycle_once()
        self._rest_since = math.nan
        while not self._at_rest():
            self._cycle_once()
            self._check_position_deadline(target_rad, deadline)

    def _check_position_deadline(self, target_rad: float, deadline: float) -> None:
        if self._deadline > deadline:
            raise BenchFault(
                f"the arm cannot be held at {math.degrees(target_rad):.0f}° under the load of "
                f"{self._load_to_nm:g} Nm (--loads): it is at {math.degrees(self._elevation_rad):.1f}° "
                f"with {self._tension_n:.0f} N on the cable; a load the TDU cannot lift there is too "
                "heavy for this bench")

    def _spool_per_elevation(self, elevation_rad: float) -> float:
        """Spool radians per radian of elevation: the cable's lever over the pulley's (cuff geometry),
        at least a tenth of the lever at 90° (near the bottom the lever vanishes)."""
        geometry = self.config.geometry
        lever = max(geometry.moment_arm_m(elevation_rad), 0.1 * geometry.moment_arm_m(math.pi / 2.0))
        return lever / self.config.spool_radius_m

    def _at_rest(self) -> bool:
        """The arm has been still (the IMU's elevation speed) for ``_REST_WINDOW_S``."""
        now = self.devices.clock.now()
        if self._rest_speed_rad_s > _REST_SPEED_RAD_S:
            self._rest_since = math.nan
            return False
        if math.isnan(self._rest_since):
            self._rest_since = now
        return now - self._rest_since >= _REST_WINDOW_S

    def _learn_rest(self) -> None:
        """Learn where the spool stands with the arm at rest here, if here is a range end."""
        p = self.config.protocol
        for end in (p.low_rad, p.high_rad):
            if abs(self._elevation_rad - end) <= self.config.safety.range_margin_rad and self._arrival:
                self._ends.learn((end, self._load_to_nm, self._arrival), self._elevation_rad,
                                 self._target_rad)

    def _run_stroke(self, stroke: BenchStroke) -> bool:
        """The stroke, recorded until the arm rests; True if the arm reached its end (within half the
        range margin) on the way."""
        p = self.config.protocol
        end = p.high_rad if stroke.raising else p.low_rad
        direction = 1.0 if stroke.raising else -1.0
        key = (end, stroke.load_nm, direction)
        start_elevation = self._elevation_rad
        self._furthest_rad = start_elevation
        self._move(stroke.spool_velocity_rad_s, end, PHASE_STROKE)
        self._rest_since = math.nan
        limit = self._deadline + _STROKE_REST_LIMIT_S
        self._phase = PHASE_SETTLE
        while True:  # recorded: the arm may still be on its way (a light load lowers it slowly)
            self._cycle_once()
            if self._at_rest() or self._deadline >= limit:
                break
        rest = self._elevation_rad
        if direction * (rest - start_elevation) > 0.0:
            # Where it rested is a point of the spool-to-elevation map of this end, load and
            # direction (short of the end, too: the next stroke aims from it).
            self._ends.learn(key, rest, self._target_rad)
            self._ends.note_excursion(key, abs(stroke.spool_velocity_rad_s),
                                      direction * (self._furthest_rad - rest))
        return direction * (end - self._furthest_rad) <= self.config.safety.range_margin_rad / 2.0

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
                # A fast stroke with no stroke to this end seen yet expects to turn as far past its
                # rest as the range margin: it aims half of it short.
                fast = speed > self.config.position_speed_rad_s
                # It covers half the range at least: a stroke that rests short is run again, with
                # the excursion at its own speed learned (not extrapolated from a slower one).
                spool_stop = self._ends.stop((stop_rad, self._load_to_nm, direction), speed,
                                             allowed_rad=safety.range_margin_rad / 2.0,
                                             unknown_rad=safety.range_margin_rad if fast else 0.0,
                                             most_short_rad=abs(p.high_rad - p.low_rad) / 2.0)
                if spool_stop is not None:
                    # The spool target at which the arm rested at this end before (through the taut
                    # cable): brake so that the target, which decelerates exactly, stops there.
                    braking = direction * (spool_stop - self._target_rad) <= (
                        v * v / (2.0 * p.spool_acceleration_rad_s2) + v * self._cycle_dt_s)
                else:
                    # First visit of this end by a slow stroke: the elevation/spool ratio of the move
                    # so far. It aims half the range margin short, as the arm lags the spool through
                    # the sheath and catches up when it stops (10° past the end measured); resting
                    # short, it is run again from what it learned.
                    ratio = moved / travelled if abs(travelled) >= _MIN_TRAVEL_FOR_RATIO_RAD else 0.0
                    short = safety.range_margin_rad / 2.0
                    remaining = direction * (stop_rad - self._elevation_rad) - short
                    braking = remaining <= abs(ratio) * stopping_spool
            step = p.spool_acceleration_rad_s2 * self._cycle_dt_s  # by the clock, as the target
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
        if math.isnan(self._fast_mean_rad):
            self._fast_mean_rad = self._slow_mean_rad = sample.elevation_rad
        self._fast_mean_rad += min(self._cycle_dt_s / _REST_FAST_S, 1.0) * (sample.elevation_rad
                                                                              - self._fast_mean_rad)
        self._slow_mean_rad += min(self._cycle_dt_s / _REST_SLOW_S, 1.0) * (sample.elevation_rad
                                                                              - self._slow_mean_rad)
        lag_s = _REST_SLOW_S - _REST_FAST_S
        self._rest_speed_rad_s = abs(self._fast_mean_rad - self._slow_mean_rad) / lag_s
        low, high = p.low_rad - safety.range_margin_rad, p.high_rad + safety.range_margin_rad
        raising = self._stroke is not None and self._stroke.raising
        if self._phase in (PHASE_TAKE_UP, PHASE_POSITION) or (raising and self._phase != PHASE_SETTLE):
            # The arm may hang below the range until it is brought to a stroke's start, and a raising
            # stroke may start below it (a heavy load at the low end); the guard is for overshoots.
            low = -math.pi
        if not low <= sample.elevation_rad <= high:
            raise BenchFault(f"elevation {math.degrees(sample.elevation_rad):.1f}° left the bench's range "
                             f"({math.degrees(low):.0f}°–{math.degrees(high):.0f}°)")
        cell = self.devices.load_cell
        failure = getattr(cell, "failure", None)
        if failure is not None:
            raise BenchFault(f"load cell lost: {failure}")
        # Its age counts from the end of a host stall too, as the IMU's: the reader could not run.
        # A reader the host starves (no attempt either) is a gap in the data (bench_cell).
        reading, fresh = self._cell_watch.read(cell, now, self._stall_end_s)
        if not fresh:
            if self._phase in (PHASE_HOLD, PHASE_STROKE, PHASE_SETTLE):
                self._gap_in_attempt = True  # its rows would hold a stale tension: run it again
            pull = self._pull_n()
            if pull > safety.max_tension_n:  # the tension limit, from the TDU's torque meanwhile
                raise BenchFault(f"tension about {pull:.0f} N (from the TDU's torque, the load cell's "
                                 f"reader starved) over the limit ({safety.max_tension_n:.0f} N)")
            return
        if reading is None:  # none yet, and the clock started less than the limit ago
            return
        self._tension_n = reading.tension_n
        if reading.tension_n > safety.max_tension_n:
            raise BenchFault(f"tension {reading.tension_n:.0f} N over the limit "
                             f"({safety.max_tension_n:.0f} N)")
        self._check_load_cell(now, reading.tension_n)

    def _check_load_cell(self, now: float, tension_n: float) -> None:
        """A load cell that reads (almost) nothing while the TDU pulls, or while the arm rests on the
        cable under its load (at any load: the tension is then load / the cuff's lever)."""
        safety = self.config.safety
        pull = self._pull_n()
        implied = 0.0
        settled = now - self._load_ramp_start_s >= self.config.load_ramp_s
        if self._phase == PHASE_HOLD and settled and self._load_to_nm > 0.0:
            lever = self.config.geometry.moment_arm_m(self._elevation_rad)
            implied = self._load_to_nm / lever if lever > 0.0 else 0.0
        if pull > safety.load_cell_check_pull_n and tension_n < safety.load_cell_min_n:
            problem = f"while the TDU pulls about {pull:.0f} N"
        elif tension_n < safety.load_cell_min_fraction * implied:
            problem = (f"while the arm rests on the cable under {self._load_to_nm:g} Nm at "
                       f"{math.degrees(self._elevation_rad):.0f}° (about {implied:.0f} N)")
        else:
            self._deaf_cell_since = math.nan
            return
        if math.isnan(self._deaf_cell_since):
            self._deaf_cell_since = now
        elif now - self._deaf_cell_since > safety.load_cell_window_s:
            raise BenchFault(f"the load cell reads {tension_n:.1f} N {problem}: check its wiring and "
                             "calibration")

    def _check_take_up_cell(self, velocity_rad_s: float, stalled_since: float) -> float:
        """During the take-up: a spool stalled against the taut cable, pulling more than the
        pretension, while the load cell reads nothing, is the load cell's fault (not a loose cable).
        Returns since when the spool is stalled so (NaN: it is not)."""
        now = self.devices.clock.now()
        spool_speed = abs(self._tdu_state.velocity_rad_s) if self._tdu_state is not None else math.inf
        pull = self._pull_n()
        if not (spool_speed < 0.2 * velocity_rad_s and pull > self.config.slack.pretension_n
                and self._tension_n < self.config.safety.load_cell_min_n):
            return math.nan
        if math.isnan(stalled_since):
            return now
        if now - stalled_since > _TAKE_UP_STALL_S:
            raise BenchFault(f"the load cell reads {self._tension_n:.1f} N while the TDU pulls about "
                             f"{pull:.0f} N on the taut cable (the spool stalled): check its wiring and "
                             "calibration")
        return stalled_since

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
        command = self._mannequin_command_nm
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
        if self._phase in (PHASE_HOLD, PHASE_STROKE, PHASE_SETTLE) and self._stroke is not None \
                and tdu is not None:
            self._rows.append((t, tdu.torque_nm, tdu.velocity_rad_s, self._tension_n, self._elevation_rad,
                               trial))
        self._log_rows.append((
            t, trial, self._phase, self._target_rad, velocity, tdu.position_rad if tdu else nan,
            self._mannequin_command_nm, man.torque_nm if man else nan, man.position_rad if man else nan,
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

    def _wall_torque_nm(self) -> float:
        """The soft walls' torque now (:mod:`bowden.runtime.bench_walls`), on the joint's encoder."""
        state = self._mannequin_state
        if state is None:
            return 0.0
        elevation = self._joint.elevation_rad(state.position_rad, self._elevation_rad)
        lowering = self._stroke is not None and not self._stroke.raising and self._phase in (
            PHASE_STROKE, PHASE_SETTLE)
        return self._walls.torque_nm(elevation, state.velocity_rad_s, lowering=lowering)

    def _reference_joint(self) -> None:
        state = self._mannequin_state
        # Both still (an IMU that froze reads as still while the joint moves).
        if state is not None and self._rest_speed_rad_s <= _REST_SPEED_RAD_S \
                and abs(state.velocity_rad_s) <= _REST_SPEED_RAD_S:
            self._joint.update(state.position_rad, self._elevation_rad, self._cycle_dt_s)

    def _check_imu_against_joint(self, target_rad: float, deadline: float) -> None:
        """With the arm at rest between positioning steps: the IMU's elevation against the mannequin
        joint's (referenced to the IMU at rest before), apart by more than half the range margin
        with the joint still for ``_IMU_JOINT_WINDOW_S``. An IMU that froze or fell off makes the
        steps chase an error that never shrinks, which would otherwise be named as a load too heavy;
        an IMU that lags (its samples late on a busy host, the arm falling under a heavy load) catches
        up within the window."""
        until = self._deadline + _IMU_JOINT_WINDOW_S
        while True:
            state = self._mannequin_state
            if state is None or not math.isfinite(self._joint.offset_rad):
                return
            joint = self._joint.elevation_rad(state.position_rad, self._elevation_rad)
            if abs(joint - self._elevation_rad) <= self.config.safety.range_margin_rad / 2.0:
                return
            if abs(state.velocity_rad_s) > _REST_SPEED_RAD_S:
                until = self._deadline + _IMU_JOINT_WINDOW_S  # the joint still moves
            elif self._deadline >= until:
                raise BenchFault(f"the IMU does not follow the arm: it reads "
                                 f"{math.degrees(self._elevation_rad):.1f}° with the mannequin's joint "
                                 f"at {math.degrees(joint):.1f}° (is it on the arm?)")
            self._cycle_once()
            self._check_position_deadline(target_rad, deadline)

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
        load_from = self._mannequin_command_nm
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
