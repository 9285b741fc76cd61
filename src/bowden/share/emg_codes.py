"""A stored EMG channel's samples as EDF/BDF digital codes, without loss wherever they allow it.

The store keeps each muscle's samples as they came (:mod:`bowden.store.emg_chunks`): the simulated
study's 16-bit codes, an imported EDF's int16 or BDF's 24-bit codes, an XDF stream's float32 or
float64 values, an int32 stream's counts. EDF holds 16-bit and BDF 24-bit integers. So each channel's
stored values ``s`` become file codes ``c`` with a step: ``s = c × step`` exactly, in the stored
values' own format:

- integer values within the file's range: the values themselves (step 1);
- integer values wider than 24 bits that share a factor (a 24-bit count shifted left into 32 bits):
  the values divided by their greatest common divisor;
- float values on a lattice (an amplifier's integer counts times its unit gain, which is how an
  LSL amplifier app makes its float32 microvolts, e.g. TMSi SAGA's): the counts, found by dividing by
  the smallest gap between values (or a half, third, quarter of it) and refining the step by least
  squares; kept only if
  ``float32(c × step)`` gives every stored value back bit for bit;
- anything else (floats that no 24-bit lattice reproduces): quantised to 24 bits over the channel's
  range, and flagged ``exact=False`` so that the writer keeps the exact values beside the file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class FileCodes:
    """One channel's digital samples for the file: ``stored = codes × step`` (exactly when ``exact``)."""

    codes: np.ndarray[Any, Any]  # int64, within the file's digital range
    step: float
    exact: bool
    max_error: float  # largest |stored − codes × step| in stored units (0.0 when exact)


def file_codes(stored: np.ndarray[Any, Any], digital_range: tuple[int, int]) -> FileCodes:
    """The codes and step of :class:`FileCodes` for ``stored`` in ``digital_range`` (see the module)."""
    low, high = digital_range
    if stored.dtype.kind in "iu":
        values = stored.astype(np.int64)
        if _fits(values, low, high):
            return FileCodes(values, 1.0, True, 0.0)
        divisor = int(np.gcd.reduce(np.abs(values))) if values.size else 1
        if divisor > 1 and _fits(values // divisor, low, high):
            return FileCodes(values // divisor, float(divisor), True, 0.0)
    else:
        lattice = _float_lattice(stored, low, high)
        if lattice is not None:
            return lattice
    return _quantised(stored, low, high)


def stored_values(codes: FileCodes, dtype: np.dtype[Any]) -> np.ndarray[Any, Any]:
    """The stored values the codes stand for, in the store's format: ``codes × step`` as ``dtype``."""
    if dtype.kind in "iu":
        return (codes.codes * int(codes.step)).astype(dtype)
    return (codes.codes.astype(np.float64) * codes.step).astype(dtype)


def _fits(values: np.ndarray[Any, Any], low: int, high: int) -> bool:
    return not values.size or (int(values.min()) >= low and int(values.max()) <= high)


def _float_lattice(stored: np.ndarray[Any, Any], low: int, high: int) -> FileCodes | None:
    """Integer codes whose multiples of one step give ``stored`` back bit for bit, or None."""
    values = stored.astype(np.float64)
    distinct = np.unique(values)
    if distinct.size == 1:  # a constant channel: one code
        step = float(abs(distinct[0])) or 1.0
        return FileCodes(np.rint(values / step).astype(np.int64), step, True, 0.0)
    # The smallest gap among the values nearest zero: their rounding is the finest.
    nearest = np.sort(distinct[np.argsort(np.abs(distinct))[:1024]])
    gap = float(np.min(np.diff(nearest)))
    for parts in range(1, 5):  # the smallest gap may span a few steps where few values are stored
        counts, step = _refined(values, gap / parts)
        if not _fits(counts, low, high):
            return None
        for candidate in (step, float(np.float32(step)), gap / parts):
            if np.array_equal((counts * candidate).astype(stored.dtype), stored):
                return FileCodes(counts.astype(np.int64), candidate, True, 0.0)
    return None


def _refined(values: np.ndarray[Any, Any], step: float) -> tuple[np.ndarray[Any, Any], float]:
    """Counts and step by turns, from the smallest values out: the counts of values up to 2^10 steps,
    their least-squares step, then up to 2^14 steps with that step, and so on. A rounded value is off
    by up to 2^-24 of itself, so a step from small values is good enough for the counts of values 16
    times larger, never for the largest at once."""
    for limit in (2.0**10, 2.0**14, 2.0**18, 2.0**22, math.inf):
        near = np.abs(values) <= limit * step
        counts = np.rint(values[near] / step)
        if np.any(counts):
            step = float(np.dot(values[near], counts) / np.dot(counts, counts))  # least squares through 0
    return np.rint(values / step), step


def _quantised(stored: np.ndarray[Any, Any], low: int, high: int) -> FileCodes:
    """The finest step of ``high`` codes over the channel's largest magnitude (not exact)."""
    values = stored.astype(np.float64)
    peak = float(np.max(np.abs(values))) if values.size else 0.0
    step = peak / high if peak > 0.0 else 1.0
    codes = np.clip(np.rint(values / step), low, high).astype(np.int64)
    error = float(np.max(np.abs(codes * step - values))) if values.size else 0.0
    return FileCodes(codes, step, error == 0.0, error)
