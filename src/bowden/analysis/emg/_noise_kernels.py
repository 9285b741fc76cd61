"""Compiled loops of the EMG noise model (:mod:`bowden.analysis.emg.ecg_noise`).

Each replaces a NumPy expression whose temporaries are as large as its input (a record, or a
stack of spectra) by one pass with the same arithmetic: the mean power of a stack of spectra
(as ``np.mean(X.real**2 + X.imag**2, axis=0)``, rows summed in order), the noise model's segments,
beat energies (as differences of ``np.cumsum``) and total energy (``np.sum``, pairwise) in one pass,
and a per-beat gain.
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
def _block_squares(x: NDArray[np.float64], first: int, count: int) -> float:
    """Σ x² over at most 128 terms as NumPy's pairwise sum does: below 8 one by one, else in eight
    interleaved partial sums combined pairwise, then the remainder."""
    if count < 8:
        total = 0.0
        for i in range(first, first + count):
            total += x[i] * x[i]
        return total
    partial = np.empty(8)
    for j in range(8):
        partial[j] = x[first + j] * x[first + j]
    i = 8
    while i < count - count % 8:
        for j in range(8):
            partial[j] += x[first + i + j] * x[first + i + j]
        i += 8
    total = float(
        ((partial[0] + partial[1]) + (partial[2] + partial[3]))
        + ((partial[4] + partial[5]) + (partial[6] + partial[7]))
    )
    for k in range(first + i, first + count):
        total += x[k] * x[k]
    return total


@jit
def _pairwise_squares(x: NDArray[np.float64]) -> float:
    """Σ x² summed as NumPy's pairwise sum does (``np.sum(x * x)``), to the last bit.

    NumPy splits a sum of more than 128 terms in halves (rounded down to a multiple of 8) and adds
    the halves' sums; the same tree is walked here with an explicit stack (a recursive compiled
    function cannot be loaded back from numba's cache).
    """
    first = np.empty(64, dtype=np.int64)
    count = np.empty(64, dtype=np.int64)
    stage = np.empty(64, dtype=np.int64)  # 0: not split yet, 1: left half summed, 2: both
    left = np.empty(64)
    top = 0
    first[0], count[0], stage[0] = 0, x.size, 0
    result = 0.0  # the sum of the node finished last
    while top >= 0:
        if count[top] <= 128:
            result = _block_squares(x, first[top], count[top])
            top -= 1
            continue
        half = count[top] // 2
        half -= half % 8
        if stage[top] == 0:
            stage[top] = 1
            first[top + 1], count[top + 1], stage[top + 1] = first[top], half, 0
            top += 1
        elif stage[top] == 1:
            left[top] = result
            stage[top] = 2
            first[top + 1], count[top + 1], stage[top + 1] = first[top] + half, count[top] - half, 0
            top += 1
        else:
            result = left[top] + result
            top -= 1
    return result


@jit
def noise_statistics(
    x: NDArray[np.float64], start: NDArray[np.int64], end: NDArray[np.int64], segments: NDArray[np.float64]
) -> tuple[NDArray[np.float64], float]:
    """What the noise model needs of a residual ``x``, from one pass over it (and a pairwise sum).

    Fills ``segments`` (rows x nfft) with consecutive non-overlapping pieces of ``x`` of nfft/2
    samples (fewer when ``x`` is shorter), zero-padded to nfft; returns Σ x² over each beat
    [start, end) and over the record. A beat's energy is the difference of the running sum of
    squares (accumulated in record order from 0, as ``np.cumsum(x * x)``) at its ends, and the
    record's is ``np.sum(x * x)``: both those expressions' to the last bit.
    """
    rows, nfft = segments.shape
    segment = min(nfft // 2, x.size)
    for r in range(rows):
        row = segments[r]
        for j in range(segment):
            row[j] = x[r * segment + j]
        for j in range(segment, nfft):
            row[j] = 0.0
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
    return energies, _pairwise_squares(x)


@jit
def scale_beats(
    x: NDArray[np.float64], start: NDArray[np.int64], end: NDArray[np.int64], scale: NDArray[np.float64]
) -> None:
    """Multiply each beat [start, end) of ``x`` in place by √max(scale, 0) (beats do not overlap)."""
    for b in range(start.size):
        gain = math.sqrt(max(scale[b], 0.0))
        for i in range(start[b], end[b]):
            x[i] *= gain
