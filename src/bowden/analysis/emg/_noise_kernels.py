"""Compiled loops of the EMG noise model (:mod:`bowden.analysis.emg.ecg_noise`).

Each replaces a NumPy expression whose temporaries are as large as its input (a record, or a
stack of spectra) by one pass with the same arithmetic: the mean power of a stack of spectra
(as ``np.mean(X.real**2 + X.imag**2, axis=0)``, rows summed in order), the energy of each beat
from a running sum of squares (as differences of ``np.cumsum``), and a per-beat gain.
tests/analysis/test_emg_noise_kernels.py checks them against those expressions.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from bowden.analysis.emg._kernels import jit


@jit
def mean_power(spectra: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Mean over the rows of ``|X|²`` per column (rows x bins in, bins out)."""
    rows, bins = spectra.shape
    total = np.zeros(bins)
    for r in range(rows):
        row = spectra[r]
        for k in range(bins):
            total[k] += row[k].real ** 2 + row[k].imag ** 2
    for k in range(bins):
        total[k] /= rows
    return total


@jit
def beat_energies(
    x: NDArray[np.float64], start: NDArray[np.int64], end: NDArray[np.int64]
) -> NDArray[np.float64]:
    """Σ x² over each beat [start, end), as the difference of a running sum over the record.

    The running sum accumulates in record order from 0, as ``np.cumsum(x * x)`` with a leading 0;
    a beat's energy is its value at ``end`` minus its value at ``start`` (not a sum of the beat
    alone), so the result is that expression's to the last bit.
    """
    bounds = np.concatenate((start, end))
    order = np.argsort(bounds)  # the running sum is read at the bounds in record order
    at = np.empty(bounds.size)  # its value at each bound
    k = 0
    while k < bounds.size and bounds[order[k]] == 0:
        at[order[k]] = 0.0
        k += 1
    running = 0.0
    for i in range(x.size):
        running += x[i] * x[i]
        while k < bounds.size and bounds[order[k]] == i + 1:
            at[order[k]] = running
            k += 1
    energies = np.empty(start.size)
    for b in range(start.size):
        energies[b] = at[start.size + b] - at[b]
    return energies


@jit
def scale_beats(
    x: NDArray[np.float64], start: NDArray[np.int64], end: NDArray[np.int64], scale: NDArray[np.float64]
) -> None:
    """Multiply each beat [start, end) of ``x`` in place by √max(scale, 0) (beats do not overlap)."""
    for b in range(start.size):
        gain = math.sqrt(max(scale[b], 0.0))
        for i in range(start[b], end[b]):
            x[i] *= gain
