import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bowden.errors import ParameterError
from bowden.model.transmission import (
    capstan_output_tension_n,
    friction_factor,
    friction_from_slopes,
    input_tension_n,
    multi_bend_output_tension_n,
    output_tension_n,
    pulley_radius_from_slopes,
    slopes_from_friction,
)

ks = st.floats(min_value=0.0, max_value=0.9)
tensions = st.floats(min_value=0.0, max_value=500.0)


def test_single_bend_hand_values():
    # k = 0.2: raising T_out/T_in = 0.8/1.2, lowering 1.2/0.8 (paper supplement eq. S7).
    assert output_tension_n(60.0, 0.2, +1) == pytest.approx(40.0)
    assert output_tension_n(40.0, 0.2, -1) == pytest.approx(60.0)
    assert output_tension_n(50.0, 0.2, 0) == 50.0


def test_paper_form_equals_ratio_form():
    # The paper writes T_out = T_in (1 - s 2k/(1 + s k)); check against (1 - s k)/(1 + s k) by hand.
    for k in (0.05, 0.3, 0.7):
        for s in (-1, 1):
            paper = 1.0 - s * 2.0 * k / (1.0 + s * k)
            assert output_tension_n(1.0, k, s) == pytest.approx((1 - s * k) / (1 + s * k))
            assert output_tension_n(1.0, k, s) == pytest.approx(paper)


def test_friction_factor_and_validity():
    assert friction_factor(0.2, math.pi) == pytest.approx(0.2)
    assert friction_factor(0.2, math.pi / 3) == pytest.approx(0.1)
    with pytest.raises(ParameterError, match="split larger wraps"):
        friction_factor(0.2, 4.0)
    with pytest.raises(ParameterError, match="cable_velocity_sign"):
        output_tension_n(1.0, 0.1, 2)
    with pytest.raises(ParameterError, match=r"\[0, 1\)"):
        output_tension_n(1.0, 1.0, 1)


@given(tensions, ks, st.sampled_from([-1, 0, 1]))
def test_inverse_of_forward_is_identity(t_in, k, s):
    assert input_tension_n(output_tension_n(t_in, k, s), k, s) == pytest.approx(t_in, rel=1e-12, abs=1e-12)


@given(tensions, ks)
def test_friction_opposes_motion(t_in, k):
    # Raising: the arm receives less than the motor gives; lowering: more. Monotonic in k.
    assert output_tension_n(t_in, k, 1) <= t_in <= output_tension_n(t_in, k, -1)
    assert output_tension_n(t_in, min(k + 0.05, 0.95), 1) <= output_tension_n(t_in, k, 1) + 1e-12


def test_many_small_bends_tend_to_the_capstan_law():
    mu, wrap, t_in = 0.15, math.radians(270.0), 40.0
    for s in (-1, 1):
        capstan = capstan_output_tension_n(t_in, mu, wrap, s)
        coarse = multi_bend_output_tension_n(t_in, mu, [wrap / 3] * 3, s)
        fine = multi_bend_output_tension_n(t_in, mu, [wrap / 400] * 400, s)
        assert abs(fine - capstan) < abs(coarse - capstan)
        assert fine == pytest.approx(capstan, rel=1e-4)
    assert capstan_output_tension_n(10.0, 0.1, 1.0, 1) == pytest.approx(10.0 * math.exp(-0.1))


def test_multi_bend_is_product_of_single_bends():
    k1, k2 = friction_factor(0.2, 1.0), friction_factor(0.2, 2.0)
    expected = output_tension_n(output_tension_n(30.0, k1, 1), k2, 1)
    assert multi_bend_output_tension_n(30.0, 0.2, [1.0, 2.0], 1) == pytest.approx(expected)


@given(st.floats(min_value=0.0, max_value=0.8), st.floats(min_value=0.01, max_value=0.1))
def test_slope_pair_to_k_and_back(k, radius):
    raising, lowering = slopes_from_friction(k, radius)
    assert friction_from_slopes(raising, lowering) == pytest.approx(k, abs=1e-12)
    assert pulley_radius_from_slopes(raising, lowering) == pytest.approx(radius, rel=1e-12)
    assert slopes_from_friction(friction_from_slopes(raising, lowering), radius) == pytest.approx(
        (raising, lowering), rel=1e-12
    )


def test_slope_hand_values_and_bad_pairs():
    # k = 0.1, R = 35 mm: 0.035*1.1/0.9 and 0.035*0.9/1.1.
    assert slopes_from_friction(0.1, 0.035) == pytest.approx((0.0427778, 0.0286364), rel=1e-5)
    with pytest.raises(ParameterError, match="direction split"):
        friction_from_slopes(0.02, 0.04)
    with pytest.raises(ParameterError, match="positive"):
        friction_from_slopes(-0.02, 0.04)
