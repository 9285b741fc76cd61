import math

import numpy as np
import pytest

from bowden.analysis.metrics import (
    integrate_between,
    integrate_columns_between,
    percent_error,
    rmse,
    root_mean_square,
    signed_peak,
)
from bowden.errors import ParameterError, RecordingError


def test_rmse_hand_values_and_nan_handling():
    assert rmse([1.0, 2.0, 3.0], [1.0, 2.0, 5.0]) == pytest.approx(math.sqrt(4.0 / 3.0))
    assert rmse([1.0, np.nan, 3.0], [0.0, 0.0, 0.0]) == pytest.approx(math.sqrt(5.0))
    assert math.isnan(rmse([np.nan], [1.0]))


def test_percent_error_is_torque_invariant_and_masks_small_references():
    tension = np.array([11.0, 9.0, 0.5, 22.0])
    desired = np.array([10.0, 10.0, 0.4, 20.0])
    arm = np.array([0.05, 0.08, 0.1, 0.12])
    pe = percent_error(tension, desired, min_reference=1.0)
    assert pe[[0, 1, 3]] == pytest.approx([10.0, -10.0, 10.0])
    assert math.isnan(pe[2])
    # Percent error of torque = tension x moment arm is the same (supplement, Table S1).
    assert percent_error(tension * arm, desired * arm, min_reference=0.1 * 1.0)[[0, 1, 3]] == pytest.approx(
        pe[[0, 1, 3]]
    )
    assert root_mean_square(pe) == pytest.approx(10.0)
    with pytest.raises(RecordingError, match="shape"):
        percent_error([1.0], [1.0, 2.0])
    with pytest.raises(ParameterError, match="min_reference"):
        percent_error([1.0], [1.0], min_reference=-1.0)


def test_signed_peak_keeps_the_sign_of_the_largest_magnitude():
    assert signed_peak([1.0, -5.0, 4.0, np.nan]) == (-5.0, 1)
    value, index = signed_peak([np.nan, np.nan])
    assert math.isnan(value) and index == -1


def test_integral_splits_exactly_at_a_boundary_between_grid_points():
    tau = np.linspace(0.0, 1.0, 11)
    y = 2.0 * tau + 1.0  # linear: trapezoid is exact
    turn = 0.537
    whole = integrate_between(tau, y, 0.0, 1.0)
    assert whole == pytest.approx(2.0)
    assert integrate_between(tau, y, 0.0, turn) == pytest.approx(turn**2 + turn)
    assert integrate_between(tau, y, 0.0, turn) + integrate_between(tau, y, turn, 1.0) == pytest.approx(whole)
    with pytest.raises(ParameterError, match="outside"):
        integrate_between(tau, y, -0.1, 0.5)


def test_columns_are_integrated_as_one_column_at_a_time() -> None:
    rng = np.random.default_rng(7)
    tau = np.linspace(0.0, 1.0, 101)
    values = rng.normal(size=(101, 8)).cumsum(axis=0)
    for lower, upper in ((0.0, 1.0), (0.0, 0.4567), (0.4567, 1.0), (0.3, 0.3), (0.25, 0.75)):
        together = integrate_columns_between(tau, values, lower, upper)
        one_by_one = [integrate_between(tau, values[:, k], lower, upper) for k in range(8)]
        np.testing.assert_allclose(together, one_by_one, rtol=1e-12, atol=1e-14)
    with pytest.raises(ParameterError, match="outside the grid"):
        integrate_columns_between(tau, values, -0.1, 0.5)
    with pytest.raises(ParameterError, match="shape"):
        integrate_columns_between(tau, values[:50], 0.0, 0.5)


def test_curves_are_interpolated_as_np_interp_does() -> None:
    from bowden.analysis.outcomes import interpolate_curves

    rng = np.random.default_rng(3)
    tau = np.linspace(0.0, 1.0, 201)
    data = rng.normal(size=(4, 201, 5))
    data[:, :, 1] = np.nan  # a signal absent from the trial
    data[2, 50:60, 3] = np.nan  # a gap
    for grid in (np.linspace(0.0, 1.0, 101), np.sort(rng.uniform(0.0, 1.0, 77))):
        ours = interpolate_curves(grid, tau, data)
        reference = np.stack(
            [np.stack([np.interp(grid, tau, data[r, :, s]) for s in range(5)], axis=1) for r in range(4)]
        )
        if grid.size == 101:  # nested grids: exactly np.interp's values
            np.testing.assert_array_equal(ours, reference)
        else:
            np.testing.assert_allclose(ours, reference, rtol=1e-12, atol=1e-12)
