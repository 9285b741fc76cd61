"""Compiled loops of the EMG conditioning: zero-phase SOS filtering, the sliding RMS, channel screen.

They work on a (samples x channels) C-contiguous array one row at a time, so the innermost loop runs
over the channels (contiguous in memory, vectorised) and a whole recording is filtered in one
pass instead of one strided copy per channel. The arithmetic is that of SciPy's ``sosfiltfilt``
(odd padding, ``sosfilt_zi`` initial states, direct form II transposed in the same order) and of a
``cumsum`` of squares, so the results equal SciPy's and NumPy's to rounding
(tests/analysis/test_emg_pipeline_fixture.py pins them at 1e-9).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, TypeVar, cast

import numba
import numpy as np
from numpy.typing import NDArray

_F = TypeVar("_F", bound=Callable[..., Any])


def jit(func: _F) -> _F:
    """Compile ``func`` in nopython mode, cached on disk (as ``bowden.sim._kernels.jit``)."""
    return cast(_F, numba.njit(cache=True, nogil=True)(func))


@jit
def _sos_pass(
    source: NDArray[np.float64],
    target: NDArray[np.float64],
    offset: int,
    sos: NDArray[np.float64],
    z0: NDArray[np.float64],
    z1: NDArray[np.float64],
    reverse: bool,
) -> int:
    """One direct-form-II-transposed pass of ``sos`` over the rows of ``source`` (SciPy's ``sosfilt``).

    Output row r goes to ``target[r - offset]`` when that row exists (so the padding can be dropped
    without a copy; ``target`` may be ``source``). ``z0``/``z1`` (sections x channels) hold the
    initial states and are updated; with ``reverse`` the rows run from the last to the first. Each
    section's states are separate 1-D arrays so that the channel loop compiles to vector
    instructions (measured: 2.4x faster than one 3-D state array). Returns how many source values
    were not finite (counted on the way: an integer sum keeps the loop vectorised).
    """
    n, channels = source.shape
    sections = sos.shape[0]
    current = np.empty(channels)
    nonfinite = 0
    for step in range(n):
        r = n - 1 - step if reverse else step
        row = source[r]
        for c in range(channels):
            value = row[c]
            nonfinite += (value - value) != 0.0  # NaN for ±inf and NaN, 0 otherwise
            current[c] = value
        for s in range(sections):
            b0, b1, b2, a1, a2 = sos[s, 0], sos[s, 1], sos[s, 2], sos[s, 4], sos[s, 5]
            state0, state1 = z0[s], z1[s]
            for c in range(channels):
                x = current[c]
                y = b0 * x + state0[c]
                state0[c] = b1 * x - a1 * y + state1[c]
                state1[c] = b2 * x - a2 * y
                current[c] = y
        if 0 <= r - offset < target.shape[0]:
            out = target[r - offset]
            for c in range(channels):
                out[c] = current[c]
    return nonfinite


@jit
def sosfiltfilt_rows(
    x: NDArray[np.float64],
    sos: NDArray[np.float64],
    zi: NDArray[np.float64],
    edge: int,
    scratch: NDArray[np.float64],
    out: NDArray[np.float64],
) -> bool:
    """``scipy.signal.sosfiltfilt(sos, x, axis=0)`` (odd padding of ``edge`` rows; needs n > edge).

    ``zi`` is ``sosfilt_zi(sos)``; ``scratch`` holds at least (n + 2·edge)·channels values; the
    result goes to ``out`` (n x channels). Returns whether every input was finite
    (checked on the way, so the caller needs no separate pass over the data).
    """
    n, channels = x.shape
    sections = sos.shape[0]
    # The forward pass lives in the caller's scratch (at least n + 2·edge rows); it reads the record
    # itself and only the odd extensions at its ends from small arrays, so the record is not
    # copied first: 2·x[0] − x[edge − j] before it, 2·x[n−1] − x[n−2−k] after it.
    padded = scratch[: (n + 2 * edge) * channels].reshape((n + 2 * edge, channels))
    head = np.empty((edge, channels))
    tail = np.empty((edge, channels))
    for j in range(edge):
        for c in range(channels):
            head[j, c] = 2.0 * x[0, c] - x[edge - j, c]
            tail[j, c] = 2.0 * x[n - 1, c] - x[n - 2 - j, c]
    z0 = np.empty((sections, channels))
    z1 = np.empty((sections, channels))
    last = n + 2 * edge - 1
    first_row = head[0] if edge > 0 else x[0]
    for s in range(sections):  # forwards, from the steady state of the first padded row
        for c in range(channels):
            z0[s, c] = zi[s, 0] * first_row[c]
            z1[s, c] = zi[s, 1] * first_row[c]
    _sos_pass(head, padded[:edge], 0, sos, z0, z1, False)
    nonfinite = _sos_pass(x, padded[edge : edge + n], 0, sos, z0, z1, False)
    _sos_pass(tail, padded[edge + n :], 0, sos, z0, z1, False)
    for s in range(sections):  # backwards from the last row, keeping the record's rows only
        for c in range(channels):
            z0[s, c] = zi[s, 0] * padded[last, c]
            z1[s, c] = zi[s, 1] * padded[last, c]
    _sos_pass(padded, out, edge, sos, z0, z1, True)
    return nonfinite == 0


@jit
def sliding_rms_rows(x: NDArray[np.float64], width: int, out: NDArray[np.float64]) -> bool:
    """Centred sliding RMS over ``width`` rows into ``out``, shrinking at the ends; whether x was finite.

    The window of row i is rows [i − width//2, i − width//2 + width) clipped to the record. Its sum
    of squares is the difference of two running sums, each accumulated in record order exactly as
    ``np.cumsum`` does; full windows are scaled by 1/width and shrunken ones divided by their count,
    as :func:`bowden.analysis.emg.filter.emg_envelope` has always done.
    """
    n, channels = x.shape
    back = width // 2
    ahead = np.zeros(channels)  # running sum of squares up to the window's end (exclusive)
    behind = np.zeros(channels)  # the same up to its start
    hi = 0
    lo = 0
    nonfinite = 0
    inverse = 1.0 / width
    for i in range(n):
        while hi < min(i - back + width, n):
            row = x[hi]
            for c in range(channels):
                value = row[c]
                nonfinite += (value - value) != 0.0
                ahead[c] += value * value
            hi += 1
        while lo < i - back:
            row = x[lo]
            for c in range(channels):
                behind[c] += row[c] * row[c]
            lo += 1
        out_row = out[i]
        if i - back >= 0 and i - back + width <= n:
            for c in range(channels):
                out_row[c] = math.sqrt(max((ahead[c] - behind[c]) * inverse, 0.0))
        else:
            count = float(hi - lo)
            for c in range(channels):
                out_row[c] = math.sqrt(max((ahead[c] - behind[c]) / count, 0.0))
    return nonfinite == 0


@jit
def channel_screen(
    x: NDArray[np.float64],
) -> tuple[NDArray[np.int64], NDArray[np.bool_], NDArray[np.float64]]:
    """Per channel of (samples x channels): non-finite count, any two equal neighbours, and the std.

    Row-wise passes (no transposed copy) for the channel checks' usual case; the std (two-pass,
    population) only screens and is compared with a margin, so its rounding does not matter.
    """
    n, channels = x.shape
    nonfinite = np.zeros(channels, dtype=np.int64)
    repeats = np.zeros(channels, dtype=np.bool_)
    mean = np.zeros(channels)
    for i in range(n):
        for c in range(channels):
            value = x[i, c]
            nonfinite[c] += (value - value) != 0.0
            mean[c] += value
            if i > 0 and value == x[i - 1, c]:
                repeats[c] = True
    for c in range(channels):
        mean[c] /= max(n, 1)
    spread = np.zeros(channels)
    for i in range(n):
        for c in range(channels):
            deviation = x[i, c] - mean[c]
            spread[c] += deviation * deviation
    return nonfinite, repeats, np.sqrt(spread / max(n, 1))
