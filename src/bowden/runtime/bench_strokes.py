"""The identification strokes: each run until the arm rests, braked where the arm last rested at its end,
run again when it rests short or the load cell's reader starved while it was recorded.
"""

from __future__ import annotations

import logging
import math

from bowden.protocol.bench import BenchStroke
from bowden.runtime.bench_config import BenchFault
from bowden.runtime.bench_positioning import BenchPositioning
from bowden.runtime.bench_state import PHASE_HOLD, PHASE_SETTLE, PHASE_STROKE

_log = logging.getLogger(__name__)

_STROKE_ATTEMPTS = 3  # a stroke that rests short of its end is run again, learning where it rested
_GAP_RETRIES = 3  # a stroke recorded with a gap in the load cell's data is run again this often
_STROKE_REST_LIMIT_S = 4.0  # how long a stroke's record waits for the arm to come to rest
_MIN_TRAVEL_FOR_RATIO_RAD = 0.3  # spool travel before the elevation/spool ratio is trusted for braking
# Braking starts this much earlier than the stopping distance says: the IMU's sample age, a cycle,
# and the arm's lag behind the spool through the elastic cable (the simulated bench overshot 8° at
# 4 rad/s without it).
_BRAKE_LEAD_S = 0.05


class BenchStrokes(BenchPositioning):
    """Runs one stroke until it covers the range (the rows in ``self._rows``)."""

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
