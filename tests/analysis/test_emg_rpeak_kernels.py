"""The Pan–Tompkins feature kernel equals its NumPy formulation (gradient, squares, running sums)."""

from __future__ import annotations

import numpy as np
import pytest

from bowden.analysis.emg._rpeak_kernels import integrated_energy


@pytest.mark.parametrize(("n", "width"), [(5000, 300), (5000, 301), (200, 300), (2, 1), (7, 4)])
def test_integrated_energy_is_the_moving_mean_of_the_squared_gradient(n: int, width: int) -> None:
    copy = np.random.default_rng(n + width).standard_normal(n).cumsum()
    squares = (np.gradient(copy) * 2000.0) ** 2
    running = np.concatenate([[0.0], np.cumsum(squares)])
    i = np.arange(n)
    back = (width - 1) // 2
    lo = np.clip(i - back, 0, n)
    hi = np.clip(i - back + width, 0, n)
    np.testing.assert_array_equal(integrated_energy(copy, width, 2000.0), (running[hi] - running[lo]) / width)
