"""Compiled loops of the R-peak detector (:mod:`bowden.analysis.emg.rpeaks`).

The Pan–Tompkins feature and the adaptive threshold's loop over candidate peaks, with the
arithmetic of the NumPy/Python code they replace (np.gradient, np.cumsum, integer RR means), so
the detected peaks are the same (tests/analysis/test_emg_pipeline_fixture.py).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from bowden.analysis.emg._kernels import jit


@jit
def _squared_slope(copy: NDArray[np.float64], i: int, rate_hz: float) -> float:
    """``(np.gradient(copy)[i] · rate)²``: one-sided at the ends, central inside."""
    n = copy.size
    if i == 0:
        slope = (copy[1] - copy[0]) / 1.0
    elif i == n - 1:
        slope = (copy[n - 1] - copy[n - 2]) / 1.0
    else:
        slope = (copy[i + 1] - copy[i - 1]) / 2.0
    slope = slope * rate_hz
    return float(slope * slope)


@jit
def integrated_energy(copy: NDArray[np.float64], width: int, rate_hz: float) -> NDArray[np.float64]:
    """Pan–Tompkins feature: ``np.gradient(copy)·rate`` squared, centred moving mean over ``width``.

    The window of sample i is [i − (width−1)//2, … + width) clipped to the record, its sum the
    difference of a running sum accumulated in record order (as ``np.cumsum``), divided by
    ``width`` at the ends too (what ``np.convolve(..., mode="same")`` computes). Needs 2 samples.
    """
    n = copy.size
    out = np.empty(n)
    back = (width - 1) // 2
    # The running sums at the window's two ends, each accumulated in record order (the values of
    # np.cumsum at those indices) without storing the whole running sum.
    ahead = 0.0
    behind = 0.0
    hi = 0
    lo = 0
    for i in range(n):
        while hi < min(max(i - back + width, 0), n):
            ahead += _squared_slope(copy, hi, rate_hz)
            hi += 1
        while lo < min(max(i - back, 0), n):
            behind += _squared_slope(copy, lo, rate_hz)
            lo += 1
        out[i] = (ahead - behind) / width
    return out


@jit
def adaptive_threshold(
    candidates: NDArray[np.int64],
    heights: NDArray[np.float64],
    signal_level: float,
    noise_level: float,
    refractory: int,
    search_back: float,
) -> NDArray[np.int64]:
    """Pan–Tompkins level tracking over candidate peaks (see ``rpeaks._adaptive_threshold``).

    Threshold NPKI + ¼(SPKI − NPKI); a candidate above it and at least ``refractory`` after the last
    beat is a beat (SPKI ← ⅛·height + ⅞·SPKI), else noise (NPKI likewise). When the gap since the
    last beat exceeds ``search_back`` times the mean of the last 8 RR intervals, the highest
    skipped candidate above half the threshold is taken first (SPKI ← ¼·height + ¾·SPKI).
    """
    accepted = np.empty(candidates.size, dtype=np.int64)
    rr = np.empty(candidates.size, dtype=np.int64)
    count = 0  # beats accepted
    rr_count = 0
    last_index = -1  # position in candidates of the last accepted beat
    for i in range(candidates.size):
        position, height = candidates[i], heights[i]
        threshold = noise_level + 0.25 * (signal_level - noise_level)
        if count > 0 and rr_count > 0:
            recent = min(rr_count, 8)
            total = 0
            for k in range(rr_count - recent, rr_count):
                total += rr[k]
            rr_mean = total / recent  # integers: exact up to this one division
            if position - accepted[count - 1] > search_back * rr_mean and last_index + 1 < i:
                best = last_index + 1  # the first of the highest skipped candidates
                for k in range(last_index + 2, i):
                    if heights[k] > heights[best]:
                        best = k
                if heights[best] > 0.5 * threshold and candidates[best] - accepted[count - 1] >= refractory:
                    rr[rr_count] = candidates[best] - accepted[count - 1]
                    rr_count += 1
                    accepted[count] = candidates[best]
                    count += 1
                    last_index = best
                    signal_level = 0.25 * heights[best] + 0.75 * signal_level
        if height > threshold and (count == 0 or position - accepted[count - 1] >= refractory):
            if count > 0:
                rr[rr_count] = position - accepted[count - 1]
                rr_count += 1
            accepted[count] = position
            count += 1
            last_index = i
            signal_level = 0.125 * height + 0.875 * signal_level
        else:
            noise_level = 0.125 * height + 0.875 * noise_level
    return accepted[:count].copy()
