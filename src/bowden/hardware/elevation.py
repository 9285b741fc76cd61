"""Humeral elevation from one upper-arm IMU: quaternion → elevation, gyro → elevation velocity.

With the trunk upright, elevation is the angle between the humerus and the downward vertical (angles as
the ISB recommends, Wu et al. 2005, J Biomech 38:981): θ = arccos(−(R(q)·a)_z), where q is the sensor
orientation (sensor → earth, NGIMU North-West-Up frame, z up) and a the humeral axis in the sensor
frame. ``a`` comes from a static arm-down pose q₀: there the humerus points down, so a = R(q₀)ᵀ·(0, 0,
−1). Only the vertical component is used, so no heading (magnetometer, unreliable near the motor) is
needed.

Elevation velocity comes from the gyro, not from Euler angles (the plane of elevation is undefined
with the arm hanging, Wu et al. 2005): with u = R(q)·a and d = (0, 0, −1), θ = arccos(d·u) and
u̇ = ω × u give θ̇ = ω·n with n = (d × u)/|d × u| = (u_y, −u_x, 0)/sin θ, ω the angular velocity in
the earth frame. Near θ = 0 the axis n is undefined; callers fall back to a filtered difference.

Plain floats and tuples: this runs for every IMU message in the receive thread.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from bowden.errors import ParameterError

Quaternion = tuple[float, float, float, float]  # (w, x, y, z)
Vector = tuple[float, float, float]
DOWN: Vector = (0.0, 0.0, -1.0)


def quaternion_normalised(q: Sequence[float]) -> Quaternion:
    """``q`` scaled to unit norm; NaNs if the norm is zero or not finite."""
    w, x, y, z = (float(c) for c in q)
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if not (norm > 0.0 and math.isfinite(norm)):
        return (math.nan, math.nan, math.nan, math.nan)
    return (w / norm, x / norm, y / norm, z / norm)


def quaternion_multiply(p: Quaternion, q: Quaternion) -> Quaternion:
    """Hamilton product p ⊗ q (rotate by q, then by p)."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    )


def quaternion_conjugate(q: Quaternion) -> Quaternion:
    """The inverse rotation of a unit quaternion."""
    return (q[0], -q[1], -q[2], -q[3])


def quaternion_from_axis_angle(axis: Sequence[float], angle_rad: float) -> Quaternion:
    """Unit quaternion of a rotation by ``angle_rad`` about ``axis`` (need not be unit length)."""
    ax, ay, az = (float(c) for c in axis)
    norm = math.sqrt(ax * ax + ay * ay + az * az)
    if not norm > 0.0:
        raise ParameterError("rotation axis must be non-zero")
    s = math.sin(0.5 * angle_rad) / norm
    return (math.cos(0.5 * angle_rad), ax * s, ay * s, az * s)


def rotate(q: Quaternion, v: Vector) -> Vector:
    """R(q)·v for a unit quaternion q (expanded form of q ⊗ v ⊗ q*)."""
    w, x, y, z = q
    vx, vy, vz = v
    # t = 2 (q_vec × v); v' = v + w t + q_vec × t
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (
        vx + w * tx + (y * tz - z * ty),
        vy + w * ty + (z * tx - x * tz),
        vz + w * tz + (x * ty - y * tx),
    )


@dataclass(frozen=True, kw_only=True)
class ArmDownCalibration:
    """The humeral axis in the sensor frame (unit vector), from a static arm-down pose."""

    axis: Vector

    def __post_init__(self) -> None:
        if len(self.axis) != 3 or not all(math.isfinite(c) for c in self.axis):
            raise ParameterError(f"ArmDownCalibration.axis must be 3 finite numbers, got {self.axis!r}")
        norm = math.sqrt(sum(c * c for c in self.axis))
        if abs(norm - 1.0) > 1e-6:
            raise ParameterError(f"ArmDownCalibration.axis must be a unit vector, norm is {norm:.6f}")

    @classmethod
    def from_quaternions(cls, quaternions: Sequence[Sequence[float]]) -> ArmDownCalibration:
        """Average a = R(qᵢ)ᵀ·(0, 0, −1) over the orientations of a still, hanging arm.

        Raises
        ------
        ParameterError
            If no finite orientation was given.
        """
        sx = sy = sz = 0.0
        count = 0
        for raw in quaternions:
            q = quaternion_normalised(raw)
            if math.isnan(q[0]):
                continue
            ax, ay, az = rotate(quaternion_conjugate(q), DOWN)
            sx, sy, sz = sx + ax, sy + ay, sz + az
            count += 1
        norm = math.sqrt(sx * sx + sy * sy + sz * sz)
        if count == 0 or not norm > 0.0:
            raise ParameterError("arm-down calibration needs at least one finite orientation")
        return cls(axis=(sx / norm, sy / norm, sz / norm))


def humerus_direction(q: Quaternion, calibration: ArmDownCalibration) -> Vector:
    """Unit humerus direction in the earth frame, u = R(q)·a."""
    return rotate(q, calibration.axis)


def elevation_from_direction(u: Vector) -> float:
    """θ = arccos(−u_z), rad, clamped against rounding (NaN stays NaN)."""
    c = -u[2]
    if c > 1.0:
        c = 1.0
    elif c < -1.0:
        c = -1.0
    return math.acos(c)


def elevation_velocity_from_gyro(
    q: Quaternion, u: Vector, gyro_sensor_rad_s: Vector, min_sin_elevation: float
) -> float:
    """θ̇ = ω·n (rad/s) from the body-frame gyro; NaN where sin θ < ``min_sin_elevation``."""
    sin_elevation = math.hypot(u[0], u[1])
    if not sin_elevation >= min_sin_elevation:
        return math.nan
    wx, wy, _ = rotate(q, gyro_sensor_rad_s)
    return (wx * u[1] - wy * u[0]) / sin_elevation


class DifferenceVelocity:
    """Elevation velocity by a first-order low-passed finite difference (fallback near arm-down).

    Parameters
    ----------
    cutoff_hz
        Corner frequency of the low-pass applied to (θₖ − θₖ₋₁)/Δt.
    """

    def __init__(self, cutoff_hz: float = 20.0) -> None:
        if not (math.isfinite(cutoff_hz) and cutoff_hz > 0.0):
            raise ParameterError(f"cutoff_hz must be positive, got {cutoff_hz!r}")
        self._tau_s = 1.0 / (2.0 * math.pi * cutoff_hz)
        self._time_s = math.nan
        self._elevation_rad = math.nan
        self.velocity_rad_s = 0.0

    def update(self, time_s: float, elevation_rad: float) -> float:
        """Feed one sample; returns the filtered velocity (rad/s)."""
        dt = time_s - self._time_s
        if dt > 0.0 and math.isfinite(elevation_rad) and math.isfinite(self._elevation_rad):
            raw = (elevation_rad - self._elevation_rad) / dt
            alpha = dt / (self._tau_s + dt)
            self.velocity_rad_s += alpha * (raw - self.velocity_rad_s)
        if math.isfinite(elevation_rad):
            self._time_s = time_s
            self._elevation_rad = elevation_rad
        return self.velocity_rad_s
