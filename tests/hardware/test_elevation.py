"""Quaternion → humeral elevation and gyro → elevation velocity, against independent references."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from bowden.errors import ParameterError
from bowden.hardware.elevation import (
    ArmDownCalibration,
    DifferenceVelocity,
    elevation_from_direction,
    elevation_velocity_from_gyro,
    humerus_direction,
    quaternion_from_axis_angle,
    quaternion_multiply,
    quaternion_normalised,
    rotate,
)
from bowden.sim.peers.ngimu_peer import arm_gyro_rad_s, arm_orientation

unit = st.floats(-1.0, 1.0)
axes = st.tuples(unit, unit, unit).filter(lambda a: math.sqrt(sum(c * c for c in a)) > 0.1)
angles = st.floats(-math.pi, math.pi)


@given(axes, angles, st.tuples(unit, unit, unit))
def test_rotate_matches_scipy(axis: tuple[float, float, float], angle: float,
                              v: tuple[float, float, float]) -> None:
    q = quaternion_from_axis_angle(axis, angle)
    reference = Rotation.from_quat([q[1], q[2], q[3], q[0]]).apply(v)  # SciPy is scalar-last
    np.testing.assert_allclose(rotate(q, v), reference, atol=1e-12)


@given(axes, angles, axes, angles, st.tuples(unit, unit, unit))
def test_product_composes_rotations(a1: tuple[float, float, float], t1: float,
                                    a2: tuple[float, float, float], t2: float,
                                    v: tuple[float, float, float]) -> None:
    p, q = quaternion_from_axis_angle(a1, t1), quaternion_from_axis_angle(a2, t2)
    np.testing.assert_allclose(rotate(quaternion_multiply(p, q), v), rotate(p, rotate(q, v)), atol=1e-12)


def test_hand_derived_elevations() -> None:
    # Sensor frame = earth frame at rest and the humerus along sensor −z: arm-down axis (0, 0, −1).
    calibration = ArmDownCalibration.from_quaternions([(1.0, 0.0, 0.0, 0.0)])
    np.testing.assert_allclose(calibration.axis, (0.0, 0.0, -1.0), atol=1e-15)
    # 90° about x swings −z to +y: arm horizontal, 90°.
    q = quaternion_from_axis_angle((1.0, 0.0, 0.0), math.pi / 2)
    assert elevation_from_direction(humerus_direction(q, calibration)) == pytest.approx(math.pi / 2)
    # 30° about y: elevation 30° whatever the sign of the rotation.
    for sign in (1.0, -1.0):
        q = quaternion_from_axis_angle((0.0, 1.0, 0.0), sign * math.radians(30.0))
        elevation = elevation_from_direction(humerus_direction(q, calibration))
        assert math.degrees(elevation) == pytest.approx(30.0)
    # A pure heading change (about vertical) never changes elevation.
    q = quaternion_from_axis_angle((0.0, 0.0, 1.0), 1.3)
    assert elevation_from_direction(humerus_direction(q, calibration)) == pytest.approx(0.0, abs=1e-7)


@settings(max_examples=200)
@given(
    elevation=st.floats(0.0, math.pi),
    heading_calibration=angles,
    heading=angles,
    mount_axis=axes,
    mount_angle=angles,
)
def test_elevation_is_recovered_for_any_mounting_and_heading(
    elevation: float, heading_calibration: float, heading: float,
    mount_axis: tuple[float, float, float], mount_angle: float,
) -> None:
    mounting = quaternion_from_axis_angle(mount_axis, mount_angle)
    calibration = ArmDownCalibration.from_quaternions([arm_orientation(0.0, heading_calibration, mounting)])
    q = arm_orientation(elevation, heading, mounting)
    assert elevation_from_direction(humerus_direction(q, calibration)) == pytest.approx(elevation, abs=1e-6)


@settings(max_examples=200)
@given(
    elevation=st.floats(math.radians(6.0), math.radians(174.0)),
    velocity=st.floats(-10.0, 10.0),
    heading=angles,
    mount_axis=axes,
    mount_angle=angles,
)
def test_gyro_velocity_equals_the_elevation_rate(
    elevation: float, velocity: float, heading: float,
    mount_axis: tuple[float, float, float], mount_angle: float,
) -> None:
    mounting = quaternion_from_axis_angle(mount_axis, mount_angle)
    calibration = ArmDownCalibration.from_quaternions([arm_orientation(0.0, heading, mounting)])
    q = arm_orientation(elevation, heading, mounting)
    gyro = arm_gyro_rad_s(q, velocity, heading)
    u = humerus_direction(q, calibration)
    estimate = elevation_velocity_from_gyro(q, u, gyro, math.sin(math.radians(5.0)))
    assert estimate == pytest.approx(velocity, abs=1e-9)


def test_gyro_velocity_agrees_with_a_numerical_derivative() -> None:
    # Independent check: differentiate the elevation of a rotating sensor numerically.
    mounting = quaternion_from_axis_angle((1.0, 2.0, 3.0), 0.7)
    calibration = ArmDownCalibration.from_quaternions([arm_orientation(0.0, 0.2, mounting)])
    spin_world = (0.3, -1.1, 0.4)  # rad/s, constant, earth frame
    angle_rate = math.sqrt(sum(c * c for c in spin_world))
    q0 = arm_orientation(math.radians(50.0), 0.2, mounting)

    def orientation(t: float) -> tuple[float, float, float, float]:
        return quaternion_multiply(quaternion_from_axis_angle(spin_world, angle_rate * t), q0)

    dt = 1e-6
    numeric = (elevation_from_direction(humerus_direction(orientation(dt), calibration))
               - elevation_from_direction(humerus_direction(orientation(-dt), calibration))) / (2 * dt)
    q = orientation(0.0)
    gyro_body = rotate((q[0], -q[1], -q[2], -q[3]), spin_world)
    analytic = elevation_velocity_from_gyro(q, humerus_direction(q, calibration), gyro_body, 0.05)
    assert analytic == pytest.approx(numeric, rel=1e-6)


def test_gyro_velocity_is_undefined_near_arm_down() -> None:
    calibration = ArmDownCalibration(axis=(0.0, 0.0, -1.0))
    q = quaternion_from_axis_angle((0.0, 1.0, 0.0), math.radians(2.0))
    u = humerus_direction(q, calibration)
    assert math.isnan(elevation_velocity_from_gyro(q, u, (0.0, 1.0, 0.0), math.sin(math.radians(5.0))))


def test_calibration_averages_noisy_poses() -> None:
    rng = np.random.default_rng(1)
    mounting = quaternion_from_axis_angle((0.2, 0.9, -0.4), 1.1)
    poses = []
    for _ in range(200):
        wobble = quaternion_from_axis_angle(rng.normal(size=3), math.radians(1.0) * rng.normal())
        poses.append(quaternion_multiply(wobble, arm_orientation(0.0, 0.0, mounting)))
    calibration = ArmDownCalibration.from_quaternions(poses)
    exact = ArmDownCalibration.from_quaternions([arm_orientation(0.0, 0.0, mounting)])
    assert math.degrees(math.acos(min(1.0, float(np.dot(calibration.axis, exact.axis))))) < 0.3


def test_calibration_rejects_nothing_finite() -> None:
    with pytest.raises(ParameterError, match="at least one finite"):
        ArmDownCalibration.from_quaternions([(math.nan, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0)])
    with pytest.raises(ParameterError, match="unit vector"):
        ArmDownCalibration(axis=(0.0, 0.0, -2.0))


def test_normalisation_of_degenerate_quaternions() -> None:
    assert all(math.isnan(c) for c in quaternion_normalised((0.0, 0.0, 0.0, 0.0)))
    assert quaternion_normalised((2.0, 0.0, 0.0, 0.0)) == (1.0, 0.0, 0.0, 0.0)


def test_difference_velocity_converges_on_a_ramp() -> None:
    estimator = DifferenceVelocity(cutoff_hz=20.0)
    for k in range(500):
        estimator.update(k * 0.005, 0.1 + 0.8 * k * 0.005)
    assert estimator.velocity_rad_s == pytest.approx(0.8, rel=1e-6)
    # A NaN sample neither poisons the state nor moves it.
    assert estimator.update(2.5, math.nan) == pytest.approx(0.8, rel=1e-6)
