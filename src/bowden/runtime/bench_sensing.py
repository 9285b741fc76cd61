"""The bench's sensors read once a cycle, and the watchdogs on them and on both motors.

Every check raises :class:`~bowden.runtime.bench_config.BenchFault` naming the fault; the run brings
both motors to the safe state (docs/identification.md, "On your bench", Faults).
"""

from __future__ import annotations

import math

from bowden.runtime.bench_config import BenchFault
from bowden.runtime.bench_state import (
    _REST_FAST_S,
    _REST_SLOW_S,
    PHASE_HOLD,
    PHASE_MANNEQUIN_MOVE,
    PHASE_POSITION,
    PHASE_SETTLE,
    PHASE_STROKE,
    PHASE_STUDY,
    PHASE_TAKE_UP,
    BenchState,
)

_TAKE_UP_STALL_S = 0.5  # a stalled spool pulling this long with a silent load cell: the load cell


class BenchSensing(BenchState):
    """Reads the IMU and the load cell each cycle and watches them and the motors."""

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
        # The later segments move the arm over their own range (the study's cycle reaches 100°).
        top = max(p.high_rad, self._segment_high_rad)
        low, high = p.low_rad - safety.range_margin_rad, top + safety.range_margin_rad
        raising = self._stroke is not None and self._stroke.raising
        if self._phase in (PHASE_TAKE_UP, PHASE_POSITION, PHASE_MANNEQUIN_MOVE) or (
                raising and self._phase != PHASE_SETTLE):
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
            if self._phase in (PHASE_HOLD, PHASE_STROKE, PHASE_SETTLE, PHASE_STUDY):
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
