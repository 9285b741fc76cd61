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
    n_beats: int,
    out: NDArray[np.float64],
) -> None:
    """Each beat's template into ``out``: mean of its ``n_beats`` neighbours (n//2 before), not itself.

    Grid: beats x offsets ``first_offset … first_offset + width − 1`` from the R-peaks (width:
    ``out``'s columns); a cell counts where its sample lies inside its beat [start, end). Sums over
    the beat axis come from running sums accumulated beat by beat (as ``np.cumsum(axis=0)``); a cell
    with no neighbour is 0. A beat's own cells are one run of columns, so the loops split at its
    ends instead of testing every cell.
    """
    count_beats, width = out.shape
    sums = np.empty((count_beats + 1, width))
    counts = np.empty((count_beats + 1, width), dtype=np.int64)
    sums[0, :] = 0.0
    counts[0, :] = 0
    for k in range(count_beats):
        origin = peaks[k] + first_offset  # sample of column 0
        lo = min(max(start[k] - origin, 0), width)
        hi = min(max(end[k] - origin, lo), width)
        for j in range(lo):
            sums[k + 1, j] = sums[k, j] + 0.0
            counts[k + 1, j] = counts[k, j]
        for j in range(lo, hi):
            sums[k + 1, j] = sums[k, j] + y[origin + j]
            counts[k + 1, j] = counts[k, j] + 1
        for j in range(hi, width):
            sums[k + 1, j] = sums[k, j] + 0.0
            counts[k + 1, j] = counts[k, j]
    for k in range(count_beats):
        first = min(max(k - n_beats // 2, 0), count_beats)
        last = min(max(k + (n_beats - n_beats // 2) + 1, 0), count_beats)
        origin = peaks[k] + first_offset
        lo = min(max(start[k] - origin, 0), width)
        hi = min(max(end[k] - origin, lo), width)
        for j in range(width):
            own = y[origin + j] if lo <= j < hi else 0.0
            total = sums[last, j] - sums[first, j] - own
            count = counts[last, j] - counts[first, j] - (1 if lo <= j < hi else 0)
            out[k, j] = total / count if count > 0 else 0.0


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
