"""Compiled loops of the ECG template subtraction (:mod:`bowden.analysis.emg.ecg`).

Each replaces a chain of NumPy operations over the beats x offsets grid (tens of full-size
temporaries per channel) by one pass with the same arithmetic in the same order, so the results are
those of the NumPy code to the last bit (tests/analysis/test_emg_pipeline_fixture.py pins them).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from bowden.analysis.emg._kernels import jit


@jit
def moving_templates(
    y: NDArray[np.float64],
    peaks: NDArray[np.int64],
    start: NDArray[np.int64],
    end: NDArray[np.int64],
    first_offset: int,
    width: int,
    n_beats: int,
) -> NDArray[np.float64]:
    """Each beat's template: mean of its ``n_beats`` neighbours (n//2 before, the rest after), not itself.

    Grid: beats x offsets ``first_offset … first_offset + width − 1`` from the R-peaks; a cell
    counts where its sample lies inside its beat [start, end). Sums over the beat axis come from
    running sums accumulated beat by beat (as ``np.cumsum(axis=0)``); a cell with no neighbour is 0.
    """
    count_beats = peaks.size
    sums = np.zeros((count_beats + 1, width))
    counts = np.zeros((count_beats + 1, width), dtype=np.int64)
    beats = np.zeros((count_beats, width))
    inside = np.zeros((count_beats, width), dtype=np.int64)
    for k in range(count_beats):
        for j in range(width):
            index = peaks[k] + first_offset + j
            if start[k] <= index < end[k]:
                beats[k, j] = y[min(max(index, 0), y.size - 1)]
                inside[k, j] = 1
            sums[k + 1, j] = sums[k, j] + beats[k, j]
            counts[k + 1, j] = counts[k, j] + inside[k, j]
    out = np.zeros((count_beats, width))
    for k in range(count_beats):
        lo = min(max(k - n_beats // 2, 0), count_beats)
        hi = min(max(k + (n_beats - n_beats // 2) + 1, 0), count_beats)
        for j in range(width):
            total = sums[hi, j] - sums[lo, j] - beats[k, j]
            count = counts[hi, j] - counts[lo, j] - inside[k, j]
            if count > 0:
                out[k, j] = total / count
    return out


@jit
def subtract_templates(
    y: NDArray[np.float64],
    peaks: NDArray[np.int64],
    start: NDArray[np.int64],
    end: NDArray[np.int64],
    template: NDArray[np.float64],
    half: int,
) -> NDArray[np.float64]:
    """``y`` minus each beat's template row (offsets −half…half) placed at its R-peak, within [start, end)."""
    cleaned = y.copy()
    for b in range(peaks.size):
        for i in range(max(start[b], peaks[b] - half), min(end[b], peaks[b] + half + 1)):
            cleaned[i] -= template[b, i - peaks[b] + half]
    return cleaned
