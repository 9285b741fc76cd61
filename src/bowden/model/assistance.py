"""Gravity assistance: the cable tension that supports a fraction of the arm's weight.

Support conditions (paper, "Protocol"): a constant pretension of 10 N ("pre"), or a fraction of the
gravitational shoulder torque (25 %, 50 %) turned into cable tension through the moment arm,

    T_des(θ) = max(T_floor, support · τ_g(θ) / r(θ)).

Whether the paper kept 10 N as a floor under the support laws is not stated; its RMSE ratios fit a
floor (paper, "Results": the tracking errors of 25 % and 50 %), so the floor is a parameter (0
disables it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from bowden.errors import ParameterError
from bowden.model.anthropometry import ArmModel
from bowden.model.geometry import CuffGeometry

PRETENSION: Literal["pretension"] = "pretension"


@dataclass(frozen=True, kw_only=True)
class AssistanceParameters:
    """How much to assist.

    Parameters
    ----------
    support
        Fraction of the gravitational shoulder torque to support, in [0, 1], or ``"pretension"`` for
        the constant-tension condition.
    floor_tension_n
        Lowest tension commanded under a support law, N (keeps the cable taut; 0 disables).
    pretension_n
        Constant tension of the pretension condition, N.
    """

    support: float | Literal["pretension"] = 0.5
    floor_tension_n: float = 10.0
    pretension_n: float = 10.0

    def __post_init__(self) -> None:
        if isinstance(self.support, str):
            if self.support != PRETENSION:
                raise ParameterError(
                    f"support must be a fraction in [0, 1] or 'pretension', got {self.support!r}"
                )
        elif not (isinstance(self.support, int | float) and 0.0 <= self.support <= 1.0):
            is_percent = isinstance(self.support, int | float) and self.support > 1
            hint = " (a percentage? use 0.5 for 50 %)" if is_percent else ""
            raise ParameterError(f"support must be a fraction in [0, 1], got {self.support!r}{hint}")
        for name in ("floor_tension_n", "pretension_n"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 <= value <= 200.0):
                raise ParameterError(f"{name} must be between 0 and 200 N, got {value!r}")

    @property
    def is_pretension(self) -> bool:
        return self.support == PRETENSION


def desired_tension_n(
    elevation_rad: float,
    arm: ArmModel,
    geometry: CuffGeometry,
    assistance: AssistanceParameters,
) -> float:
    """Desired cable tension at the arm anchor, N (reference implementation; the controller inlines it).

    Where the moment arm is not positive (beyond the cuff's reach) the support law cannot act and
    the floor tension is returned.
    """
    if assistance.is_pretension:
        return assistance.pretension_n
    support = float(assistance.support)
    moment_arm = geometry.moment_arm_m(elevation_rad)
    if moment_arm <= 0.0:
        return assistance.floor_tension_n
    supported = support * arm.gravity_torque_nm(elevation_rad) / moment_arm
    return max(assistance.floor_tension_n, supported)


def desired_joint_torque_nm(
    elevation_rad: float,
    arm: ArmModel,
    geometry: CuffGeometry,
    assistance: AssistanceParameters,
) -> float:
    """The shoulder torque the desired tension produces, T_des·r(θ), Nm (the paper's torque reference)."""
    return desired_tension_n(elevation_rad, arm, geometry, assistance) * max(
        0.0, geometry.moment_arm_m(elevation_rad)
    )
