import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bowden.errors import ParameterError
from bowden.model import (
    AssistanceParameters,
    CuffGeometry,
    Subject,
    arm_model,
    desired_joint_torque_nm,
    desired_tension_n,
)

ARM = arm_model(Subject(height_m=1.70, mass_kg=63.0, sex="female"), hand_load_kg=0.5)
GEOMETRY = CuffGeometry()


def test_support_law_by_hand_at_90_degrees():
    theta = math.pi / 2
    tau_g = ARM.gravity_torque_nm(theta)
    r = GEOMETRY.moment_arm_m(theta)
    half = AssistanceParameters(support=0.5)
    assert desired_tension_n(theta, ARM, GEOMETRY, half) == pytest.approx(0.5 * tau_g / r)
    assert desired_joint_torque_nm(theta, ARM, GEOMETRY, half) == pytest.approx(0.5 * tau_g)


def test_floor_and_pretension():
    low = math.radians(5.0)
    assert desired_tension_n(low, ARM, GEOMETRY, AssistanceParameters(support=0.25)) == 10.0
    no_floor = AssistanceParameters(support=0.25, floor_tension_n=0.0)
    assert 0.0 < desired_tension_n(low, ARM, GEOMETRY, no_floor) < 10.0
    pre = AssistanceParameters(support="pretension", pretension_n=12.0)
    for theta in (0.0, 1.0, 2.0):
        assert desired_tension_n(theta, ARM, GEOMETRY, pre) == 12.0


def test_paper_reference_torque_magnitude():
    # docs/design.md, "Cuff geometry": the paper's numbers imply a reference torque near 3.8 Nm at 50 %
    # (cycle average).
    thetas = [math.radians(20.0 + 80.0 * i / 200) for i in range(201)]
    half = AssistanceParameters(support=0.5)
    mean = sum(desired_joint_torque_nm(t, ARM, GEOMETRY, half) for t in thetas) / len(thetas)
    assert 3.0 < mean < 4.8


@given(st.floats(min_value=0.0, max_value=math.radians(150.0)), st.floats(min_value=0.0, max_value=1.0))
def test_never_negative_and_monotonic_in_support(theta, support):
    params = AssistanceParameters(support=support, floor_tension_n=0.0)
    more = AssistanceParameters(support=min(1.0, support + 0.1), floor_tension_n=0.0)
    t = desired_tension_n(theta, ARM, GEOMETRY, params)
    assert t >= 0.0
    assert desired_tension_n(theta, ARM, GEOMETRY, more) >= t


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"support": 50}, "percentage"),
        ({"support": -0.1}, "fraction"),
        ({"support": "pre"}, "pretension"),
        ({"floor_tension_n": -1.0}, "floor_tension_n"),
        ({"pretension_n": math.inf}, "pretension_n"),
    ],
)
def test_invalid_assistance(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        AssistanceParameters(**kwargs)
