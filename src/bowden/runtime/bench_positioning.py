"""The unrecorded moves between strokes: the arm brought to a stroke's start and held there while the
mannequin's load ramps in, a slow scouting move to an end not learned yet, the rests learned.
"""

from __future__ import annotations

import math

from bowden.protocol.bench import BenchStroke
from bowden.runtime.bench_config import BenchFault
from bowden.runtime.bench_cycle import BenchCycle
from bowden.runtime.bench_state import _REST_SPEED_RAD_S, PHASE_POSITION, joint_rad

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


class BenchPositioning(BenchCycle):
    """Servoes the arm to a stroke's start on the IMU, in steps by the cuff's geometry."""

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
            joint = self._joint.elevation_rad(joint_rad(state), self._elevation_rad)
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

    def _learn_rest(self) -> None:
        """Learn where the spool stands with the arm at rest here, if here is a range end."""
        p = self.config.protocol
        for end in (p.low_rad, p.high_rad):
            if abs(self._elevation_rad - end) <= self.config.safety.range_margin_rad and self._arrival:
                self._ends.learn((end, self._load_to_nm, self._arrival), self._elevation_rad,
                                 self._target_rad)
