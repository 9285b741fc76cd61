import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bowden.errors import ParameterError
from bowden.model import CuffGeometry


def test_default_geometry_reference_values():
    # docs/design.md, "Cuff geometry": r(20 deg) ~ 0.05 m, r(110 deg) ~ 0.12 m; by hand 0.04912, 0.11994.
    g = CuffGeometry()
    assert g.moment_arm_m(math.radians(20.0)) == pytest.approx(0.04912, abs=1e-5)
    assert g.moment_arm_m(math.radians(110.0)) == pytest.approx(0.11994, abs=1e-5)


@given(st.floats(min_value=0.0, max_value=math.radians(155.0)))
def test_moment_arm_is_minus_cable_length_rate(theta):
    # Virtual work: the cable shortens by r per radian of elevation, r = -dL/dtheta.
    g = CuffGeometry()
    h = 1e-6
    numeric = -(g.cable_length_m(theta + h) - g.cable_length_m(theta - h)) / (2 * h)
    assert g.moment_arm_m(theta) == pytest.approx(numeric, rel=1e-6, abs=1e-9)


@given(st.floats(min_value=0.0, max_value=math.radians(159.0)))
def test_moment_arm_positive_and_bounded_before_rest_angle(theta):
    g = CuffGeometry()
    r = g.moment_arm_m(theta)
    # The perpendicular distance cannot exceed the shorter of the two arms.
    assert 0.0 < r <= min(g.exit_distance_m, g.anchor_distance_m) + 1e-12


def test_no_support_beyond_rest_angle():
    g = CuffGeometry()
    assert g.moment_arm_m(g.max_elevation_rad + 0.1) < 0.0


@pytest.mark.parametrize(
    "kwargs",
    [{"exit_distance_m": 0.0}, {"anchor_distance_m": 12.0}, {"rest_angle_rad": 160.0}],
)
def test_invalid_geometry(kwargs):
    with pytest.raises(ParameterError):
        CuffGeometry(**kwargs)
