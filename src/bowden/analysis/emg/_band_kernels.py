"""Compiled zero-phase filtering of a few columns by a two-section filter (the R-peak detector's).

The detector band-passes only the ECG-contaminated channels (usually two) with a second-order
Butterworth band-pass: two sections. Row-wise over so few channels the generic kernel
(:func:`bowden.analysis.emg._kernels.sosfiltfilt_rows`) spends its time entering its channel loops
and moving the filter states through memory; here two channels run side by side with all eight
states in registers, each recursion waiting only on its own arithmetic. The arithmetic is that of
SciPy's ``sosfiltfilt`` (odd padding, ``sosfilt_zi`` initial states, direct form II transposed in
the same order), so the results equal SciPy's to the last bit (tests/analysis/test_emg_band_kernels.py).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from bowden.analysis.emg._kernels import jit


@jit
def _odd_padded(x: NDArray[np.float64], column: int, edge: int, out: NDArray[np.float64]) -> None:
    """Column ``column`` of ``x`` with ``edge`` odd-extended samples before and after, into ``out``."""
    n = x.shape[0]
    for j in range(edge):
        out[j] = 2.0 * x[0, column] - x[edge - j, column]
    for i in range(n):
        out[edge + i] = x[i, column]
    for k in range(edge):
        out[edge + n + k] = 2.0 * x[n - 1, column] - x[n - 2 - k, column]


@jit
def _pass(
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    sos: NDArray[np.float64],
    zi: NDArray[np.float64],
    backwards: bool,
) -> None:
    """One pass of the two sections over the padded channels ``u`` and ``v`` together, in place.

    The states start from ``zi`` times the pass's first sample of each channel (SciPy's
    ``sosfilt_zi`` scaled as ``sosfiltfilt`` does) and live in local variables.
    """
    b00, b01, b02, a01, a02 = sos[0, 0], sos[0, 1], sos[0, 2], sos[0, 4], sos[0, 5]
    b10, b11, b12, a11, a12 = sos[1, 0], sos[1, 1], sos[1, 2], sos[1, 4], sos[1, 5]
    total = u.size
    first = total - 1 if backwards else 0
    u00, u01, u10, u11 = zi[0, 0] * u[first], zi[0, 1] * u[first], zi[1, 0] * u[first], zi[1, 1] * u[first]
    v00, v01, v10, v11 = zi[0, 0] * v[first], zi[0, 1] * v[first], zi[1, 0] * v[first], zi[1, 1] * v[first]
    for step in range(total):
        r = total - 1 - step if backwards else step
        x = u[r]
        y = b00 * x + u00
        u00 = b01 * x - a01 * y + u01
        u01 = b02 * x - a02 * y
        x = y
        y = b10 * x + u10
        u10 = b11 * x - a11 * y + u11
        u11 = b12 * x - a12 * y
        u[r] = y
        x = v[r]
        y = b00 * x + v00
        v00 = b01 * x - a01 * y + v01
        v01 = b02 * x - a02 * y
        x = y
        y = b10 * x + v10
        v10 = b11 * x - a11 * y + v11
        v11 = b12 * x - a12 * y
        v[r] = y


@jit
def sosfiltfilt_two_sections(
    x: NDArray[np.float64],
    columns: NDArray[np.int64],
    sos: NDArray[np.float64],
    zi: NDArray[np.float64],
    edge: int,
    scratch: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:
    """``sosfiltfilt(sos, x[:, columns], axis=0).T`` into ``out`` (len(columns) x n) for a 2-section ``sos``.

    ``zi`` is ``sosfilt_zi(sos)``, ``edge`` the odd padding (needs n > edge); ``scratch`` holds at
    least 2·(n + 2·edge) values. Channels are filtered in pairs (the last one alone with a copy of
    itself when their number is odd).
    """
    n = x.shape[0]
    total = n + 2 * edge
    u = scratch[:total]
    v = scratch[total : 2 * total]
    for p in range(0, columns.size, 2):
        _odd_padded(x, columns[p], edge, u)
        _odd_padded(x, columns[min(p + 1, columns.size - 1)], edge, v)
        _pass(u, v, sos, zi, False)
        _pass(u, v, sos, zi, True)
        out[p, :] = u[edge : edge + n]
        if p + 1 < columns.size:
            out[p + 1, :] = v[edge : edge + n]
