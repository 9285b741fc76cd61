"""The reference a trial shows: rest, ``repetitions`` minimum-jerk cycles, rest.

The participant display draws the same curve ahead of the present in JavaScript from the numbers of
:meth:`TrialReference.to_json` (the browser tests check that both agree); the loop records it per
cycle through :meth:`TrialReference.elevation_rad`, a plain-float function fit for the hot path.
Minimum-jerk position x = x₀ + D(10τ³ − 15τ⁴ + 6τ⁵) (Flash & Hogan 1985, J Neurosci 5:1688).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bowden.errors import ParameterError
from bowden.protocol.minimum_jerk import MinimumJerkCycle


@dataclass(frozen=True, kw_only=True)
class TrialReference:
    """Rest at the low elevation until ``start_s``, then ``repetitions`` cycles, then rest.

    Parameters
    ----------
    cycle
        The raise-and-lower cycle (low, high, peak speed).
    start_s
        Trial time (s) at which the first cycle starts (a lead-in to get ready).
    repetitions
        Number of raise-and-lower cycles (paper: 10).
    """

    cycle: MinimumJerkCycle
    start_s: float = 2.0
    repetitions: int = 10

    def __post_init__(self) -> None:
        if not (math.isfinite(self.start_s) and 0.0 <= self.start_s <= 60.0):
            raise ParameterError(f"TrialReference.start_s must be in [0, 60] s, got {self.start_s!r}")
        if isinstance(self.repetitions, bool) or not (
            isinstance(self.repetitions, int) and 1 <= self.repetitions <= 100
        ):
            raise ParameterError(f"TrialReference.repetitions must be 1–100, got {self.repetitions!r}")

    @property
    def end_s(self) -> float:
        """Trial time at which the last cycle ends."""
        return self.start_s + self.repetitions * self.cycle.period_s

    def elevation_rad(self, time_s: float) -> float:
        """Reference elevation (rad) at trial time ``time_s``; plain floats, no allocation."""
        cycle = self.cycle
        low = cycle.low_rad
        elapsed = time_s - self.start_s
        if elapsed <= 0.0 or time_s >= self.end_s:
            return low
        movement = cycle.movement_duration_s
        phase = math.fmod(elapsed, 2.0 * movement)
        raising = phase < movement
        tau = phase / movement if raising else phase / movement - 1.0
        s = tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau)
        span = cycle.high_rad - low
        return low + span * s if raising else cycle.high_rad - span * s

    def repetition(self, time_s: float) -> int:
        """The repetition in progress at ``time_s`` (1-based); 0 before the start, ``repetitions`` after."""
        if time_s < self.start_s:
            return 0
        if time_s >= self.end_s:
            return self.repetitions
        return min(self.repetitions, 1 + int((time_s - self.start_s) / self.cycle.period_s))

    def to_json(self) -> dict[str, float | int]:
        """The numbers the display needs to draw the reference itself (degrees at the edge)."""
        return {
            "low_deg": math.degrees(self.cycle.low_rad),
            "high_deg": math.degrees(self.cycle.high_rad),
            "movement_s": self.cycle.movement_duration_s,
            "start_s": self.start_s,
            "repetitions": self.repetitions,
        }
