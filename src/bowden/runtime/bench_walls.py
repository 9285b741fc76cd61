"""The soft walls the bench's mannequin motor puts beyond the protocol's range.

A lab bench uses the mannequin's own motor (an AK80-9 in torque control, applying the load) as a
brake at the range's ends: past an end by half the range margin (the positioning tolerance, so that
no rest is inside a wall) it adds a spring and a damper to its load. Above the range always: a fast
raising stroke under a light load flings the arm once the spool brakes (the cable cannot push, only
the load decelerates the arm: the first +6 rad/s stroke at 0.5 Nm reached 120.2° on the simulated
bench, past the 120° guard). Below it only during a lowering stroke (its momentum stretches the
cable: 9.8° at −4 rad/s under 1 Nm after a resume): elsewhere the arm may rest low (a raising
stroke's start under a heavy load, the slack's take-up) and the load there must be the load. The rows
inside a wall are a stroke's end, which the identification's steady-state selection leaves out.

The wall acts on the joint's own encoder (the mannequin motor's position, referenced to the IMU's
elevation at rest by :class:`JointReference`): the IMU's elevation trails a flung arm (3° at
1.4 rad/s on the simulated bench), so a wall on it engages late.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

_REFERENCE_S = 1.0  # the time constant of the joint's offset to the IMU, at rest


@dataclass(frozen=True)
class SoftWalls:
    """Where the walls stand and how stiff they are.

    Parameters
    ----------
    low_rad, high_rad
        The walls' faces: the protocol's low end less, its high end plus, half the range margin.
    stiffness_nm_rad, damping_nms_rad
        The spring and the damper (``BenchRunConfig.wall_stiffness_nm_rad``, ``wall_damping_nms_rad``).
    """

    low_rad: float
    high_rad: float
    stiffness_nm_rad: float
    damping_nms_rad: float

    def torque_nm(self, elevation_rad: float, velocity_rad_s: float, *, lowering: bool) -> float:
        """The torque to add to the load (> 0 pulls the arm down) with the joint at ``elevation_rad``
        moving at ``velocity_rad_s`` (> 0 raising); ``lowering``: a lowering stroke is under way (the
        low wall is on). A wall only pushes the arm back, never pulls it in."""
        k, d = self.stiffness_nm_rad, self.damping_nms_rad
        above = elevation_rad - self.high_rad
        if above > 0.0:
            return max(k * above + d * velocity_rad_s, 0.0)
        below = self.low_rad - elevation_rad
        if below > 0.0 and lowering:
            return min(-k * below + d * velocity_rad_s, 0.0)
        return 0.0


class JointReference:
    """The mannequin joint's angle minus the IMU's elevation, learned while the arm is still: the mean
    of the first ``_REFERENCE_S`` of rest, then a running mean with that time constant (the IMU's noise
    averages out).

    Nothing is known before that first second: one sample is not a reference. At a run's start the
    first cycle counts as still (the IMU's speed comes from running means that begin there) while
    the arm, released at 20°, begins to fall under its load and the IMU's sample lags it; an offset
    taken from that one sample put the joint 11° off the IMU at the first positioning, a fault ("the
    IMU does not follow the arm") in five full-suite runs on 2026-11-27, each time 11.2–11.4°."""

    def __init__(self) -> None:
        self.offset_rad = math.nan
        self._first_sum_rad_s = 0.0  # the first second of rest: the offsets' integral, and its length
        self._first_s = 0.0

    def update(self, joint_rad: float, elevation_rad: float, dt_s: float) -> None:
        """One sample with the arm at rest, ``dt_s`` since the last cycle."""
        offset = joint_rad - elevation_rad
        if self._first_s < _REFERENCE_S or not math.isfinite(self.offset_rad):
            self._first_sum_rad_s += offset * dt_s
            self._first_s += dt_s
            if self._first_s >= _REFERENCE_S:
                self.offset_rad = self._first_sum_rad_s / self._first_s
            return
        self.offset_rad += min(dt_s / _REFERENCE_S, 1.0) * (offset - self.offset_rad)

    def elevation_rad(self, joint_rad: float, fallback_rad: float) -> float:
        """The elevation the joint's angle says (``fallback_rad``, the IMU's, before any rest)."""
        return joint_rad - self.offset_rad if math.isfinite(self.offset_rad) else fallback_rad
