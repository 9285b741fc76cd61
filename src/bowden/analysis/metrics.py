"""Per-repetition error measures: RMSE, percent error, signed peaks, integrals on normalised time.

Definitions follow the paper's "Outcome measures" and its supplement: tracking RMSE between desired
and measured tension (and joint torque = tension · moment arm); the percent error per sample,
100·(measured − reference)/reference, whose RMSE is identical for tension and torque because the
moment arm cancels (supplement, Table S1); the peak percent error as the signed value of largest
magnitude and the normalised time at which it occurs (Tables S2, S3).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bowden.errors import ParameterError, RecordingError


def rmse(measured: ArrayLike, reference: ArrayLike) -> float:
    """Root-mean-square of ``measured − reference`` over the samples where both are finite.

    Returns NaN when no sample is usable.
    """
    error = np.asarray(measured, dtype=np.float64) - np.asarray(reference, dtype=np.float64)
    error = error[np.isfinite(error)]
    return float(np.sqrt(np.mean(np.square(error)))) if error.size else math.nan


def percent_error(
    measured: ArrayLike, reference: ArrayLike, *, min_reference: float = 0.0
) -> NDArray[np.float64]:
    """Per-sample percent error 100·(measured − reference)/reference.

    Samples whose |reference| is at most ``min_reference`` (same unit as the reference) are NaN:
    near a zero reference the ratio explodes and says nothing about tracking.
    """
    if not (math.isfinite(min_reference) and min_reference >= 0.0):
        raise ParameterError(f"min_reference must be a non-negative number, got {min_reference}")
    m = np.asarray(measured, dtype=np.float64)
    r = np.asarray(reference, dtype=np.float64)
    if m.shape != r.shape:
        raise RecordingError(f"measured {m.shape} and reference {r.shape} differ in shape")
    usable = np.isfinite(r) & (np.abs(r) > min_reference)
    return np.where(usable, 100.0 * (m - r) / np.where(usable, r, 1.0), np.nan)


def root_mean_square(values: ArrayLike) -> float:
    """RMS over the finite samples (NaN when there are none)."""
    x = np.asarray(values, dtype=np.float64)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else math.nan


def signed_peak(values: ArrayLike) -> tuple[float, int]:
    """The finite sample of largest magnitude, with its sign, and its index (NaN, -1 if none)."""
    x = np.asarray(values, dtype=np.float64)
    magnitude = np.where(np.isfinite(x), np.abs(x), -np.inf)
    if x.size == 0 or not np.isfinite(magnitude.max()):
        return math.nan, -1
    index = int(np.argmax(magnitude))
    return float(x[index]), index


def integrate_between(tau: ArrayLike, values: ArrayLike, lower: float, upper: float) -> float:
    """Trapezoidal integral of ``values(tau)`` from ``lower`` to ``upper`` with exact end points.

    The integrand is interpolated linearly at the limits, so a phase boundary that falls between
    grid points splits the integral without double counting: ∫₀¹ = ∫₀ᵘ + ∫ᵘ¹.
    """
    x = np.asarray(tau, dtype=np.float64)
    y = np.asarray(values, dtype=np.float64)
    if not (x[0] <= lower <= upper <= x[-1]):
        raise ParameterError(f"integration limits {lower}..{upper} outside the grid {x[0]}..{x[-1]}")
    inner = (x > lower) & (x < upper)
    grid = np.concatenate([[lower], x[inner], [upper]])
    curve = np.concatenate([[np.interp(lower, x, y)], y[inner], [np.interp(upper, x, y)]])
    return float(np.sum(0.5 * (curve[1:] + curve[:-1]) * np.diff(grid)))


def integrate_columns_between(
    tau: ArrayLike, values: ArrayLike, lower: float, upper: float
) -> NDArray[np.float64]:
    """:func:`integrate_between` of every column of ``values`` (shape ``(len(tau), k)``) at once."""
    x = np.asarray(tau, dtype=np.float64)
    y = np.asarray(values, dtype=np.float64)
    if y.ndim != 2 or y.shape[0] != x.size or x.size < 2:
        raise ParameterError(f"values must have shape ({x.size}, k) on a grid of ≥ 2 points, got {y.shape}")
    if not (x[0] <= lower <= upper <= x[-1]):
        raise ParameterError(f"integration limits {lower}..{upper} outside the grid {x[0]}..{x[-1]}")
    inner = (x > lower) & (x < upper)
    grid = np.concatenate([[lower], x[inner], [upper]])
    curve = np.concatenate([_row_at(x, y, lower)[None, :], y[inner], _row_at(x, y, upper)[None, :]])
    return np.asarray((0.5 * (curve[1:] + curve[:-1]) * np.diff(grid)[:, None]).sum(axis=0))


def _row_at(x: NDArray[np.float64], y: NDArray[np.float64], point: float) -> NDArray[np.float64]:
    """Every column of ``y`` interpolated linearly at ``point`` (inside the grid ``x``)."""
    j = min(max(int(np.searchsorted(x, point, side="right")) - 1, 0), x.size - 2)
    weight = (point - x[j]) / (x[j + 1] - x[j])
    return np.asarray(y[j] + weight * (y[j + 1] - y[j]))
