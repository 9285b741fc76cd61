"""The moving templates of the ECG removal equal their NumPy formulation (running sums over beats)."""

from __future__ import annotations

import numpy as np

from bowden.analysis.emg.ecg import _beat_bounds, _moving_templates


def test_moving_templates_equal_the_running_sums_over_the_beat_grid() -> None:
    rng = np.random.default_rng(5)
    peaks = np.cumsum(rng.integers(500, 900, size=60)).astype(np.int64)
    n = int(peaks[-1] + 300)  # the last beat is cut short by the record's end
    y = rng.standard_normal(n)
    start, end = _beat_bounds(peaks, n, 2000)
    half = int(max(np.max(peaks - start), np.max(end - 1 - peaks))) + 4
    offsets = np.arange(-half, half + 1)
    for n_beats in (40, 7, 1, 200):
        index = np.clip(peaks[:, np.newaxis] + offsets, 0, n - 1)
        inside = (peaks[:, np.newaxis] + offsets >= start[:, np.newaxis]) & (
            peaks[:, np.newaxis] + offsets < end[:, np.newaxis]
        )
        beats = np.where(inside, y[index], 0.0)
        sums = np.concatenate([np.zeros((1, offsets.size)), np.cumsum(beats, axis=0)])
        counts = np.concatenate([np.zeros((1, offsets.size), dtype=np.int64), np.cumsum(inside, axis=0)])
        k = np.arange(peaks.size)
        lo = np.clip(k - n_beats // 2, 0, peaks.size)
        hi = np.clip(k + (n_beats - n_beats // 2) + 1, 0, peaks.size)
        total = sums[hi] - sums[lo] - beats
        count = counts[hi] - counts[lo] - inside
        want = np.where(count > 0, total / np.maximum(count, 1), 0.0)
        np.testing.assert_array_equal(_moving_templates(y, peaks, start, end, offsets, n_beats), want)
