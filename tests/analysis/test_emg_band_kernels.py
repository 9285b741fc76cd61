"""The zero-phase band-passes (all channels; the detector's columns) equal SciPy's ``sosfiltfilt`` exactly."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal as sps

from bowden.analysis.emg.zero_phase import zero_phase_bandpass, zero_phase_bandpass_columns


@pytest.mark.parametrize(("columns", "order"), [([3, 5], 2), ([2], 2), ([1, 4, 6], 2), ([0, 7], 3), ([5], 1)])
def test_columns_filtered_as_scipy_sosfiltfilt(columns: list[int], order: int) -> None:
    rng = np.random.default_rng(len(columns) + order)
    x = rng.standard_normal((3001, 8)).cumsum(axis=0)  # a drifting signal: the padding matters
    sos = sps.butter(order, [5.0, 30.0], btype="bandpass", fs=2000.0, output="sos")
    got = zero_phase_bandpass_columns(x, columns, 2000.0, 5.0, 30.0, order)
    want = sps.sosfiltfilt(sos, x[:, columns], axis=0).T
    assert got.shape == want.shape and got[0].flags.c_contiguous
    np.testing.assert_array_equal(got, want)


def test_a_record_not_longer_than_the_padding_is_refused_as_scipy_does() -> None:
    with pytest.raises(ValueError, match="padlen"):
        zero_phase_bandpass_columns(np.ones((15, 2)), [0], 2000.0, 5.0, 30.0, 2)


@pytest.mark.parametrize("row", [0, 1, 1500, 2999, 3000])
def test_the_band_pass_reports_a_non_finite_sample_anywhere(row: int) -> None:
    x = np.random.default_rng(row).standard_normal((3001, 4))
    filtered, finite = zero_phase_bandpass(x, 2000.0, 20.0, 400.0, 3)
    sos = sps.butter(3, [20.0, 400.0], btype="bandpass", fs=2000.0, output="sos")
    assert finite
    np.testing.assert_array_equal(filtered, sps.sosfiltfilt(sos, x, axis=0))
    x[row, 2] = np.inf if row % 2 else np.nan
    assert not zero_phase_bandpass(x, 2000.0, 20.0, 400.0, 3)[1]
