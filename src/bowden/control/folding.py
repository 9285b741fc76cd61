"""The constants both compensation laws fold into their step closures (cuff, assistance, limits)."""

from __future__ import annotations

import math
from typing import NamedTuple

from bowden.control.limits import ControllerLimits
from bowden.model.anthropometry import STANDARD_GRAVITY_M_S2, ArmModel
from bowden.model.assistance import AssistanceParameters
from bowden.model.geometry import CuffGeometry


class Folded(NamedTuple):
    """Products and bounds precomputed once, so that a step multiplies instead of looking them up."""

    ab: float  # a·b of the cuff geometry
    aabb: float  # a² + b²
    two_ab: float  # 2·a·b
    psi: float  # the cuff's rest angle
    pretension: float  # constant tension, N; NaN marks the support law
    support_moment: float  # support·g·Σmd: τ_g(θ)·support is this times sin θ
    floor: float
    max_tension: float
    min_torque: float
    max_torque: float
    max_rate: float
    nominal_dt: float
    elev_min: float
    elev_max: float  # the limits' and the cuff's reach, whichever is lower
    max_vel: float
    max_motor_vel: float


def fold(
    arm: ArmModel, geometry: CuffGeometry, assistance: AssistanceParameters, limits: ControllerLimits
) -> Folded:
    a, b = geometry.exit_distance_m, geometry.anchor_distance_m
    if assistance.is_pretension:
        pretension, support_moment = assistance.pretension_n, 0.0
    else:
        pretension = math.nan
        support_moment = float(assistance.support) * STANDARD_GRAVITY_M_S2 * arm.total_moment_kg_m
    return Folded(
        ab=a * b,
        aabb=a * a + b * b,
        two_ab=2.0 * a * b,
        psi=geometry.rest_angle_rad,
        pretension=pretension,
        support_moment=support_moment,
        floor=assistance.floor_tension_n,
        max_tension=limits.max_tension_n,
        min_torque=limits.min_torque_nm,
        max_torque=limits.max_torque_nm,
        max_rate=limits.max_torque_rate_nm_s,
        nominal_dt=limits.nominal_period_s,
        elev_min=limits.elevation_min_rad,
        elev_max=min(limits.elevation_max_rad, geometry.max_elevation_rad),
        max_vel=limits.max_elevation_velocity_rad_s,
        max_motor_vel=limits.max_motor_velocity_rad_s,
    )
