"""Cuff geometry: the cable's moment arm about the shoulder as a function of humeral elevation.

The cable leaves the shoulder cuff at distance a from the glenohumeral joint and is anchored on the
upper-arm cuff at distance b along the humerus. With ψ the angle between the two at the joint when the
arm hangs (θ = 0), the angle at elevation θ is α = ψ − θ and the perpendicular distance from the joint
to the cable line (law of cosines for the cable length) is

    r(θ) = a·b·sin α / sqrt(a² + b² − 2ab·cos α).

The paper does not publish its geometry; the defaults (a = 0.12 m, b = 0.18 m, ψ = 160°) give
r(20°) ≈ 0.05 m and r(110°) ≈ 0.12 m, an average lever arm near the ≈ 0.10 m the paper's numbers imply
(docs/design.md, "Cuff geometry"; the paper does not publish its geometry). The cable can only support the
arm while α > 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bowden.errors import ParameterError


@dataclass(frozen=True, kw_only=True)
class CuffGeometry:
    """Cable routing at the shoulder.

    Parameters
    ----------
    exit_distance_m
        a: joint centre to the cable exit on the shoulder cuff, m.
    anchor_distance_m
        b: joint centre to the cable anchor on the upper-arm cuff, along the humerus, m.
    rest_angle_rad
        ψ: angle between exit and anchor directions at the joint with the arm hanging, rad.
    """

    exit_distance_m: float = 0.12
    anchor_distance_m: float = 0.18
    rest_angle_rad: float = math.radians(160.0)

    def __post_init__(self) -> None:
        for name in ("exit_distance_m", "anchor_distance_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 < value <= 1.0):
                raise ParameterError(f"{name} must be in (0, 1] m, got {value!r}")
        if not (math.isfinite(self.rest_angle_rad) and 0.0 < self.rest_angle_rad <= math.pi):
            raise ParameterError(
                f"rest_angle_rad must be in (0, pi], got {self.rest_angle_rad!r} (degrees?)"
            )

    def cable_length_m(self, elevation_rad: float) -> float:
        """Straight cable length between exit and anchor, m."""
        a, b = self.exit_distance_m, self.anchor_distance_m
        alpha = self.rest_angle_rad - elevation_rad
        return math.sqrt(a * a + b * b - 2.0 * a * b * math.cos(alpha))

    def moment_arm_m(self, elevation_rad: float) -> float:
        """r(θ), m. Positive while the cable can lift the arm (α > 0); ≤ 0 beyond ψ."""
        a, b = self.exit_distance_m, self.anchor_distance_m
        alpha = self.rest_angle_rad - elevation_rad
        return a * b * math.sin(alpha) / math.sqrt(a * a + b * b - 2.0 * a * b * math.cos(alpha))

    @property
    def max_elevation_rad(self) -> float:
        """Elevation where the moment arm vanishes (α = 0): no support possible beyond it."""
        return self.rest_angle_rad
