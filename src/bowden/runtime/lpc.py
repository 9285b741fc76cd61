"""Exact integer linear prediction of 16-bit codes (the ``lpc`` filter of the column codec).

As FLAC does: each sample is predicted from the ``order`` before it with integer coefficients and a
right shift, ``pred[i] = (Σ c[j]·x[i-1-j]) >> shift``, and the residual ``x[i] − pred[i]`` is kept,
wrapped to the codes' width so it inverts exactly (``x[i] = wrap(pred[i] + r[i])``, the prediction
being made from samples already restored). The first ``order`` samples keep their first difference.
The coefficients are fitted per block (autocorrelation normal equations) and stored with it, so any
fit is lossless; a good fit only makes the residual smaller. On the simulated sEMG the residual
compresses about 6 % better than the first difference.

Compiled with numba (cached on disk); this module is imported only when a block uses the filter.
"""

from __future__ import annotations

from typing import Any, Final

import numba
import numpy as np
from numpy.typing import NDArray

ORDER: Final = 8
SHIFT: Final = 12  # coefficients in units of 2⁻¹²: finer gains nothing measurable on sEMG
_MAX_COEF: Final = 1 << 24  # keeps Σ c·x inside int64 for 32-bit codes and order ≤ 32
_MIN_ROWS: Final = 8 * ORDER


def fit(codes: NDArray[np.integer[Any]], order: int = ORDER) -> NDArray[np.int64] | None:
    """Integer coefficients (units of 2⁻SHIFT) predicting ``codes``, or None where prediction is not
    worth it (a short block, a constant or degenerate one)."""
    if codes.size < max(_MIN_ROWS, 4 * order):
        return None
    r = np.empty(order + 1)
    _autocorrelation(codes.astype(np.float64), r)
    if not r[0] > 0.0:
        return None
    toeplitz = r[np.abs(np.subtract.outer(np.arange(order), np.arange(order)))]
    toeplitz[np.diag_indices(order)] *= 1.0 + 1e-9  # a whisker of white noise keeps it invertible
    try:
        coefficients = np.linalg.solve(toeplitz, r[1:])
    except np.linalg.LinAlgError:
        return None
    scaled: NDArray[np.int64] = np.rint(coefficients * (1 << SHIFT)).astype(np.int64)
    return scaled if bool(np.all(np.abs(scaled) < _MAX_COEF)) else None


def residual(
    codes: NDArray[np.integer[Any]], coefficients: NDArray[np.int64], shift: int = SHIFT
) -> NDArray[Any]:
    """The prediction residual of ``codes`` (same dtype, wrapped)."""
    bits = codes.dtype.itemsize * 8
    out = np.empty(codes.size, dtype=np.int64)
    _residual(codes.astype(np.int64), coefficients, shift, bits, out)
    return out.astype(codes.dtype)


def restore(
    residuals: NDArray[np.integer[Any]], coefficients: NDArray[np.int64], shift: int = SHIFT
) -> NDArray[Any]:
    """The codes whose :func:`residual` is ``residuals``, bit for bit."""
    bits = residuals.dtype.itemsize * 8
    out = np.empty(residuals.size, dtype=np.int64)
    _restore(residuals.astype(np.int64), coefficients, shift, bits, out)
    return out.astype(residuals.dtype)


@numba.njit(cache=True, nogil=True)
def _autocorrelation(x: NDArray[np.float64], r: NDArray[np.float64]) -> None:
    # One pass in compiled code: numpy's dot per lag costs a BLAS call (and its threads) each.
    y = x - x.mean()
    for k in range(r.size):
        acc = 0.0
        for i in range(k, y.size):
            acc += y[i] * y[i - k]
        r[k] = acc


@numba.njit(cache=True, nogil=True)
def _wrap(value: int, bits: int) -> int:
    half = 1 << (bits - 1)
    return ((value + half) & ((1 << bits) - 1)) - half


@numba.njit(cache=True, nogil=True)
def _residual(
    x: NDArray[np.int64], c: NDArray[np.int64], shift: int, bits: int, out: NDArray[np.int64]
) -> None:
    order = c.size
    for i in range(min(order, x.size)):
        out[i] = x[i] if i == 0 else _wrap(x[i] - x[i - 1], bits)
    for i in range(order, x.size):
        acc = 0
        for j in range(order):
            acc += c[j] * x[i - 1 - j]
        out[i] = _wrap(x[i] - (acc >> shift), bits)


@numba.njit(cache=True, nogil=True)
def _restore(
    r: NDArray[np.int64], c: NDArray[np.int64], shift: int, bits: int, out: NDArray[np.int64]
) -> None:
    order = c.size
    for i in range(min(order, r.size)):
        out[i] = r[i] if i == 0 else _wrap(out[i - 1] + r[i], bits)
    for i in range(order, r.size):
        acc = 0
        for j in range(order):
            acc += c[j] * out[i - 1 - j]
        out[i] = _wrap((acc >> shift) + r[i], bits)
