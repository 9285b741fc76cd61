import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bowden.errors import ParameterError
from bowden.model import STANDARD_GRAVITY_M_S2, Subject, arm_gravity_torque_nm, arm_model


def test_reference_man_matches_hand_derivation():
    # docs/design.md, "Cuff geometry and gravity" (de Leva 1996): 75 kg, 1.75 m man -> 10.9 Nm at 90 deg
    # for the arm, +3.0 Nm for 0.5 kg in the hand.
    man = Subject(height_m=1.75, mass_kg=75.0, sex="male")
    arm_only = arm_gravity_torque_nm(man, math.pi / 2, hand_load_kg=0.0)
    with_load = arm_gravity_torque_nm(man, math.pi / 2, hand_load_kg=0.5)
    assert arm_only == pytest.approx(10.9, abs=0.05)
    assert with_load - arm_only == pytest.approx(3.0, abs=0.06)


def test_segment_values_by_hand():
    # Female at the de Leva reference stature: lengths are the table's, masses the fractions.
    woman = Subject(height_m=1.735, mass_kg=60.0, sex="female")
    arm = arm_model(woman, hand_load_kg=0.0)
    upper, fore, hand = arm.segments
    assert upper.length_m == pytest.approx(0.2751)
    assert upper.mass_kg == pytest.approx(0.0255 * 60)
    assert upper.com_from_shoulder_m == pytest.approx(0.5754 * 0.2751)
    assert fore.com_from_shoulder_m == pytest.approx(0.2751 + 0.4559 * 0.2643)
    assert hand.com_from_shoulder_m == pytest.approx(0.2751 + 0.2643 + 0.7474 * 0.0780)
    expected = STANDARD_GRAVITY_M_S2 * sum(s.mass_kg * s.com_from_shoulder_m for s in arm.segments)
    assert arm.gravity_torque_nm(math.pi / 2) == pytest.approx(expected)


@given(st.floats(min_value=0.0, max_value=math.pi))
def test_torque_follows_sine_of_elevation(theta):
    subject = Subject(height_m=1.70, mass_kg=63.0, sex="female")
    peak = arm_gravity_torque_nm(subject, math.pi / 2)
    assert arm_gravity_torque_nm(subject, theta) == pytest.approx(peak * math.sin(theta), abs=1e-12)


def test_scales_with_mass_and_stature():
    base = arm_gravity_torque_nm(Subject(height_m=1.6, mass_kg=60.0, sex="male"), 1.0, 0.0)
    heavier = arm_gravity_torque_nm(Subject(height_m=1.6, mass_kg=90.0, sex="male"), 1.0, 0.0)
    taller = arm_gravity_torque_nm(Subject(height_m=2.0, mass_kg=60.0, sex="male"), 1.0, 0.0)
    assert heavier == pytest.approx(1.5 * base)
    assert taller == pytest.approx(1.25 * base)


def test_inertia_is_plausible():
    # de Leva 1996 segments: I ~ 0.45-0.65 kg m^2 for the arm with a hand-held load.
    arm = arm_model(Subject(height_m=1.70, mass_kg=63.0, sex="female"), hand_load_kg=0.5)
    assert 0.3 < arm.moment_of_inertia_kg_m2 < 0.7


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"height_m": 170.0, "mass_kg": 63.0, "sex": "female"}, "centimetres"),
        ({"height_m": 1.7, "mass_kg": 0.0, "sex": "female"}, "mass_kg"),
        ({"height_m": 1.7, "mass_kg": 63.0, "sex": "f"}, "sex"),
        ({"height_m": math.nan, "mass_kg": 63.0, "sex": "male"}, "height_m"),
    ],
)
def test_invalid_subjects_name_the_field(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        Subject(**kwargs)


def test_invalid_hand_load():
    with pytest.raises(ParameterError, match="hand_load_kg"):
        arm_model(Subject(height_m=1.7, mass_kg=63.0, sex="male"), hand_load_kg=-1.0)
