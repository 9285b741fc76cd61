"""Bowden-sheath transmission laws: tension in at the motor, tension out at the arm.

Single bend (paper, supplement §1): the normal force on the cable is N = (T_in + T_out)·sin(φ/2) and
Coulomb friction f = sgn(V)·μ·N opposes the cable's motion, so with k = μ·sin(φ/2)

    T_out = T_in · (1 − s·k) / (1 + s·k),   s = sgn(V_cable)

where s = +1 while raising (cable moves towards the motor: the motor pulls against friction) and
s = −1 while lowering (the arm pulls cable out: friction helps the motor). The law holds for φ ≤ 180°.
Several bends multiply; for many small bends of total wrap Φ the product tends to the capstan law
T_out = T_in · exp(−s·μ·Φ).

Identification fits motor torque = intercept + slope·T_out per direction. With torque = R·T_in the
ideal slopes are R·(1+k)/(1−k) raising and R·(1−k)/(1+k) lowering, so their ratio
((1+k)/(1−k))² recovers k (supplement, eq. S5).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from bowden.errors import ParameterError


def _check_sign(cable_velocity_sign: float) -> float:
    if cable_velocity_sign not in (-1, 0, 1):
        raise ParameterError(
            f"cable_velocity_sign must be -1 (lowering), 0 (static) or +1 (raising), "
            f"got {cable_velocity_sign!r}"
        )
    return float(cable_velocity_sign)


def _check_k(k: float) -> None:
    if not (0.0 <= k < 1.0):
        raise ParameterError(f"k = mu*sin(phi/2) must be in [0, 1), got {k!r}")


def friction_factor(mu: float, wrap_angle_rad: float) -> float:
    """k = μ·sin(φ/2) of one bend; φ must be in [0, π] (the single-bend law's validity)."""
    if not (mu >= 0.0 and math.isfinite(mu)):
        raise ParameterError(f"mu must be a finite non-negative number, got {mu!r}")
    if not (0.0 <= wrap_angle_rad <= math.pi):
        raise ParameterError(
            f"wrap_angle_rad must be in [0, pi] for the single-bend law, got {wrap_angle_rad!r}; "
            "split larger wraps into several bends"
        )
    return mu * math.sin(0.5 * wrap_angle_rad)


def output_tension_n(input_tension_n: float, k: float, cable_velocity_sign: float) -> float:
    """Tension at the arm from tension at the motor through one bend.

    Parameters
    ----------
    input_tension_n
        T_in, N (motor side).
    k
        μ·sin(φ/2), dimensionless, in [0, 1).
    cable_velocity_sign
        +1 raising (cable towards the motor), −1 lowering, 0 static (friction indeterminate:
        returns T_in).
    """
    s = _check_sign(cable_velocity_sign)
    _check_k(k)
    return input_tension_n * (1.0 - s * 2.0 * k / (1.0 + s * k))


def input_tension_n(output_tension_n: float, k: float, cable_velocity_sign: float) -> float:
    """Tension needed at the motor for a tension at the arm: the inverse of :func:`output_tension_n`."""
    s = _check_sign(cable_velocity_sign)
    _check_k(k)
    return output_tension_n * (1.0 + s * k) / (1.0 - s * k)


def multi_bend_output_tension_n(
    input_tension_n: float, mu: float, wrap_angles_rad: Sequence[float], cable_velocity_sign: float
) -> float:
    """Tension at the arm through several bends in series, each obeying the single-bend law."""
    s = _check_sign(cable_velocity_sign)
    tension = input_tension_n
    for wrap in wrap_angles_rad:
        k = friction_factor(mu, wrap)
        tension *= (1.0 - s * k) / (1.0 + s * k)
    return tension


def capstan_output_tension_n(
    input_tension_n: float, mu: float, wrap_angle_rad: float, cable_velocity_sign: float
) -> float:
    """Capstan (Euler–Eytelwein) law T_out = T_in·exp(−s·μ·Φ) for a total wrap Φ ≥ 0 (any size)."""
    s = _check_sign(cable_velocity_sign)
    if not (mu >= 0.0 and math.isfinite(mu)):
        raise ParameterError(f"mu must be a finite non-negative number, got {mu!r}")
    if not (wrap_angle_rad >= 0.0 and math.isfinite(wrap_angle_rad)):
        raise ParameterError(f"wrap_angle_rad must be finite and >= 0, got {wrap_angle_rad!r}")
    return input_tension_n * math.exp(-s * mu * wrap_angle_rad)


def slopes_from_friction(k: float, pulley_radius_m: float) -> tuple[float, float]:
    """Ideal (slope_raising_m, slope_lowering_m) of motor torque against arm tension for a given k."""
    _check_k(k)
    if not (pulley_radius_m > 0.0 and math.isfinite(pulley_radius_m)):
        raise ParameterError(f"pulley_radius_m must be positive, got {pulley_radius_m!r}")
    ratio = (1.0 + k) / (1.0 - k)
    return pulley_radius_m * ratio, pulley_radius_m / ratio


def friction_from_slopes(slope_raising_m: float, slope_lowering_m: float) -> float:
    """k = μ·sin(φ/2) from identified raising and lowering slopes.

    Uses m_raise/m_lower = ((1+k)/(1−k))², which needs no pulley radius: with q = sqrt(ratio),
    k = (q − 1)/(q + 1). Raising must need more torque than lowering (ratio ≥ 1).
    """
    if not (slope_raising_m > 0.0 and slope_lowering_m > 0.0):
        raise ParameterError(
            f"both slopes must be positive, got raising {slope_raising_m!r}, "
            f"lowering {slope_lowering_m!r}"
        )
    ratio = slope_raising_m / slope_lowering_m
    if ratio < 1.0:
        raise ParameterError(
            f"the raising slope ({slope_raising_m:.5g} m) is below the lowering slope "
            f"({slope_lowering_m:.5g} m): friction cannot explain that; check the direction split"
        )
    q = math.sqrt(ratio)
    return (q - 1.0) / (q + 1.0)


def pulley_radius_from_slopes(slope_raising_m: float, slope_lowering_m: float) -> float:
    """The effective pulley radius implied by a slope pair: their geometric mean (friction cancels)."""
    if not (slope_raising_m > 0.0 and slope_lowering_m > 0.0):
        raise ParameterError("both slopes must be positive")
    return math.sqrt(slope_raising_m * slope_lowering_m)
