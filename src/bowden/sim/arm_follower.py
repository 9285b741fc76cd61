"""A simulated participant who follows a trial's reference as the control loop runs it.

Used by the simulated suit in this process (:mod:`bowden.sim.backend`) and in its own process
(:mod:`bowden.sim.link.suit_process`); its own module so neither imports the other.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Protocol

import numpy as np

from bowden.protocol.minimum_jerk import MinimumJerkCycle

if TYPE_CHECKING:
    from bowden.sim.arm import PrescribedArm
    from bowden.sim.peers import WallTimePlant


class FollowedReference(Protocol):
    """What the simulated arm needs of a trial's reference (``bowden.web.reference.TrialReference``)."""

    @property
    def cycle(self) -> MinimumJerkCycle: ...

    @property
    def start_s(self) -> float: ...

    @property
    def end_s(self) -> float: ...

    def elevation_rad(self, time_s: float) -> float: ...


class ArmFollowingTheLoop:
    """A simulated participant who follows a trial's reference from the loop's first cycle on.

    The arm rests at the reference's low elevation until the loop runs, then moves as the reference
    says at loop time (rest, the repetitions, rest), as a person starts following the display.
    :meth:`arm` is the arm's motion over plant time (for the simulator); ``plant_time_at_loop_start_s``
    ties the two clocks (set on the loop's first cycle), so the recorded reference is the one the
    arm follows.
    """

    def __init__(self, reference: FollowedReference) -> None:
        self.reference = reference
        self.plant: WallTimePlant | None = None
        self.plant_time_at_loop_start_s = math.inf  # until the loop's first cycle: rest

    def arm(self) -> PrescribedArm:
        from bowden.sim.arm import PrescribedArm

        cycle, start, end = self.reference.cycle, self.reference.start_s, self.reference.end_s

        def loop_time(plant_time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            t = plant_time_s - self.plant_time_at_loop_start_s
            return t, (t > start) & (t < end)

        def elevation(plant_time_s: np.ndarray) -> np.ndarray:
            t, moving = loop_time(plant_time_s)
            return np.where(moving, cycle.elevation_rad(np.clip(t - start, 0.0, None)), cycle.low_rad)

        def velocity(plant_time_s: np.ndarray) -> np.ndarray:
            t, moving = loop_time(plant_time_s)
            return np.where(moving, cycle.elevation_velocity_rad_s(np.clip(t - start, 0.0, None)), 0.0)

        return PrescribedArm(elevation_rad=elevation, elevation_velocity_rad_s=velocity)
