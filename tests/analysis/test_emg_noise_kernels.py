"""The compiled loops of the EMG noise model equal the NumPy expressions they replace."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bowden.analysis.emg._noise_kernels import mean_power, noise_statistics, scale_beats


def _beats(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    cuts = np.sort(rng.choice(np.arange(1, n), size=40, replace=False))
    return cuts[:-1:2].astype(np.int64), cuts[1::2].astype(np.int64)  # disjoint [start, end)


def test_mean_power_is_the_mean_squared_magnitude_over_the_rows() -> None:
    rng = np.random.default_rng(0)
    spectra = np.fft.rfft(rng.standard_normal((37, 512)), axis=1)
    want = np.mean(spectra.real**2 + spectra.imag**2, axis=0)
    np.testing.assert_allclose(mean_power(spectra), want, rtol=1e-12, atol=0.0)


@pytest.mark.parametrize("n", [5000, 4100, 1000, 7, 129, 8195])
def test_noise_statistics_are_the_numpy_expressions(n: int) -> None:
    rng = np.random.default_rng(n)
    x = rng.standard_normal(n)
    start, end = _beats(rng, x.size) if n > 100 else (np.array([0, 2]), np.array([2, n]))
    nfft = 2048
    segment = min(nfft // 2, n)
    rows = max(1, n // (nfft // 2))
    segments = np.full((rows, nfft), np.nan)
    energies, total = noise_statistics(x, start, end, segments)
    squares = np.concatenate([[0.0], np.cumsum(x * x)])
    np.testing.assert_array_equal(energies, squares[end] - squares[start])
    assert total == np.sum(x * x)  # NumPy's pairwise order, to the last bit
    want = np.zeros((rows, nfft))
    want[:, :segment] = x[: rows * segment].reshape(rows, segment)
    np.testing.assert_array_equal(segments, want)
    start[0] = end[0] = 0  # an empty beat at the record's start
    energies, _ = noise_statistics(x, start, end, segments)
    np.testing.assert_array_equal(energies, squares[end] - squares[start])


def test_scale_beats_multiplies_each_beat_by_the_root_of_its_scale() -> None:
    rng = np.random.default_rng(2)
    x = rng.standard_normal(3000)
    start, end = _beats(rng, x.size)
    scale = rng.uniform(-0.2, 3.0, size=start.size)  # a negative scale counts as 0
    gain = np.ones(x.size)
    for first, stop, value in zip(start, end, scale, strict=True):
        gain[first:stop] = math.sqrt(max(float(value), 0.0))
    got = x.copy()
    scale_beats(got, start, end, scale)
    np.testing.assert_array_equal(got, x * gain)
