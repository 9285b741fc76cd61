"""Minimum-jerk elevation references (Flash & Hogan 1985), as shown to participants.

One movement from x0 to x0 + D in T seconds: x(τ) = x0 + D·(10τ³ − 15τ⁴ + 6τ⁵), τ = t/T, whose peak
speed is 1.875·|D|/T at τ = 1/2. The paper's cycle is 20° → 100° → 20°: a raising movement followed
at once by a lowering movement of the same duration, repeated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bowden.errors import ParameterError

_PEAK_SPEED_FACTOR = 1.875  # max of d/dτ (10τ³ − 15τ⁴ + 6τ⁵), at τ = 1/2


def minimum_jerk_position(tau: ArrayLike) -> NDArray[np.float64]:
    """Normalised minimum-jerk position s(τ) = 10τ³ − 15τ⁴ + 6τ⁵ for τ clipped to [0, 1]."""
    t = np.clip(np.asarray(tau, dtype=np.float64), 0.0, 1.0)
    return np.asarray(t**3 * (10.0 - 15.0 * t + 6.0 * t**2), dtype=np.float64)


@dataclass(frozen=True, kw_only=True)
class MinimumJerkCycle:
    """A raise-then-lower minimum-jerk cycle between two elevations at a given peak speed.

    Parameters
    ----------
    low_rad, high_rad
        Start/end and turning elevation (paper: 20° and 100°).
    peak_speed_rad_s
        Peak elevation speed of each movement (paper: 60, 120, 180 °/s for V1–V3).
    """

    low_rad: float = math.radians(20.0)
    high_rad: float = math.radians(100.0)
    peak_speed_rad_s: float = math.radians(60.0)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.low_rad) and math.isfinite(self.high_rad)):
            raise ParameterError("low_rad and high_rad must be finite")
        if self.high_rad <= self.low_rad:
            raise ParameterError(
                f"high_rad ({self.high_rad:.3f}) must exceed low_rad ({self.low_rad:.3f})"
            )
        if not (math.isfinite(self.peak_speed_rad_s) and self.peak_speed_rad_s > 0.0):
            raise ParameterError(f"peak_speed_rad_s must be positive, got {self.peak_speed_rad_s}")

    @property
    def movement_duration_s(self) -> float:
        """Duration of one raising (or lowering) movement: T = 1.875·D / v_peak."""
        return _PEAK_SPEED_FACTOR * (self.high_rad - self.low_rad) / self.peak_speed_rad_s

    @property
    def period_s(self) -> float:
        """Duration of one raise-and-lower cycle."""
        return 2.0 * self.movement_duration_s

    def elevation_rad(self, time_s: ArrayLike) -> NDArray[np.float64]:
        """Reference elevation at ``time_s`` (s from the start of the first cycle); periodic."""
        t = np.asarray(time_s, dtype=np.float64)
        movement = self.movement_duration_s
        phase = np.mod(t, self.period_s)
        raising = phase < movement
        tau = np.where(raising, phase / movement, (phase - movement) / movement)
        s = minimum_jerk_position(tau)
        span = self.high_rad - self.low_rad
        return np.where(raising, self.low_rad + span * s, self.high_rad - span * s)

    def elevation_velocity_rad_s(self, time_s: ArrayLike) -> NDArray[np.float64]:
        """Reference elevation velocity (> 0 raising) at ``time_s``."""
        t = np.asarray(time_s, dtype=np.float64)
        movement = self.movement_duration_s
        phase = np.mod(t, self.period_s)
        raising = phase < movement
        tau = np.where(raising, phase / movement, (phase - movement) / movement)
        ds = 30.0 * tau**2 * (1.0 - tau) ** 2  # d/dτ of 10τ³ − 15τ⁴ + 6τ⁵
        speed = (self.high_rad - self.low_rad) * ds / movement
        return np.asarray(np.where(raising, speed, -speed), dtype=np.float64)
