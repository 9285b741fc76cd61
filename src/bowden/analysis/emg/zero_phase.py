"""Zero-phase Butterworth band-pass of many channels at once (``sosfiltfilt`` in one compiled pass).

Shared by the EMG band-pass (:func:`~bowden.analysis.emg.filter.emg_filter`) and the R-peak
detector's copy (:mod:`~bowden.analysis.emg.rpeaks`). The design, its steady-state initial
conditions and the padding are computed once per (rate, band, order): a study filters thousands of
channels with the same few filters.
"""

from __future__ import annotations

import functools
import threading

import numpy as np
from numpy.typing import NDArray
from scipy import signal as sps

from bowden.analysis.emg._band_kernels import sosfiltfilt_two_sections
from bowden.analysis.emg._kernels import sosfiltfilt_rows


def zero_phase_bandpass(
    values: NDArray[np.float64], rate_hz: float, low_hz: float, high_hz: float, order: int
) -> tuple[NDArray[np.float64], bool]:
    """``sosfiltfilt(butter(order, [low_hz, high_hz], "bandpass", fs=rate_hz, output="sos"), values, 0)``.

    ``values`` is (samples x channels). Equal to SciPy's result to rounding (the same odd padding,
    initial states and recursion). Returns the filtered samples and whether every input was finite.
    Raises ``ValueError`` with SciPy's message when the record is not longer than the padding.
    """
    sos, zi, edge = _design(rate_hz, low_hz, high_hz, order)
    if values.shape[0] <= edge:
        raise ValueError(f"The length of the input vector x must be greater than padlen, which is {edge}.")
    size = (values.shape[0] + 2 * edge) * values.shape[1]
    # Large buffers come from NumPy, which asks the kernel for huge pages (few page faults), not
    # from inside the compiled code.
    out = np.empty(values.shape)
    finite = sosfiltfilt_rows(_read_only(values), sos, zi, edge, _scratch(size), out)
    return out, finite


def zero_phase_bandpass_columns(
    values: NDArray[np.float64], columns: list[int], rate_hz: float, low_hz: float, high_hz: float, order: int
) -> NDArray[np.float64]:
    """:func:`zero_phase_bandpass` of ``values[:, columns]``, returned as one row per column.

    The rows are what a per-channel consumer reads (each contiguous), without a strided copy of
    the columns first. A two-section design (order 2: the R-peak detector's) runs in the pair kernel
    with its states in registers; the result is the same to the last bit.
    """
    sos, zi, edge = _design(rate_hz, low_hz, high_hz, order)
    if values.shape[0] <= edge:
        raise ValueError(f"The length of the input vector x must be greater than padlen, which is {edge}.")
    x = _read_only(values)
    if sos.shape[0] != 2:
        filtered, _ = zero_phase_bandpass(
            np.ascontiguousarray(x[:, columns]), rate_hz, low_hz, high_hz, order
        )
        return np.ascontiguousarray(filtered.T)
    out = np.empty((len(columns), x.shape[0]))
    sosfiltfilt_two_sections(
        x, np.asarray(columns, dtype=np.int64), sos, zi, edge, _scratch(2 * (x.shape[0] + 2 * edge)), out
    )
    return out


def _read_only(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """``values`` as a C-contiguous float64 array, read-only (a copy only where the layout or type asks
    for one). numba compiles a kernel apart for a read-only and a writable input, seconds of CPU each
    on a fresh installation; the kernels only read it, so they are always given the read-only kind."""
    view = np.ascontiguousarray(values, dtype=np.float64).view()
    view.flags.writeable = False
    return view


_SCRATCH = threading.local()
_SCRATCH_KEPT = 16 * 2**20  # values (128 MB): a few minutes of 8 channels at 2 kHz


def _scratch(size: int) -> NDArray[np.float64]:
    """This thread's work buffer of at least ``size`` values, kept between calls.

    A fresh buffer of a trial's size (~9 MB) is mapped anew by the allocator on every call and each
    of its pages faulted in: measured 4300 page faults and ~10 ms per trial for the band-pass,
    rectification and envelope, more than the filtering itself.
    """
    buffer: NDArray[np.float64] | None = getattr(_SCRATCH, "buffer", None)
    if buffer is not None and buffer.size >= size:
        return buffer
    buffer = np.empty(size)
    if size <= _SCRATCH_KEPT:  # an hour-long record's buffer is not kept after its call
        _SCRATCH.buffer = buffer
    return buffer


@functools.lru_cache(maxsize=16)
def _design(
    rate_hz: float, low_hz: float, high_hz: float, order: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """Sections, ``sosfilt_zi`` and SciPy's default padding 3·(2·sections + 1 − trailing zeros)."""
    sos = np.ascontiguousarray(
        sps.butter(order, [low_hz, high_hz], btype="bandpass", fs=rate_hz, output="sos"), dtype=np.float64
    )
    taps = 2 * sos.shape[0] + 1 - min(int(np.sum(sos[:, 2] == 0)), int(np.sum(sos[:, 5] == 0)))
    zi = np.ascontiguousarray(sps.sosfilt_zi(sos), dtype=np.float64)
    sos.flags.writeable = False  # shared by every call
    zi.flags.writeable = False
    return sos, zi, 3 * taps
