"""EMG conditioning: zero-phase band-pass, full-wave rectification, sliding-RMS envelope.

The paper's "Data processing" section: a third-order zero-phase Butterworth band-pass (20–400 Hz),
rectification and a sliding 100 ms RMS window (Burden et al. 2017, following the paper's citation).
Each function takes and returns an :class:`~bowden.analysis.emg.signal.EmgSignal`, so the sampling
rate is never passed separately.

A note on "−6 dB at the cut-offs": ``butter(3, [20, 400], 'bandpass', fs=...)`` places its −3 dB
points at 20 and 400 Hz (SciPy pre-warps the band edges). Filtering forwards and backwards squares
the magnitude response, so the zero-phase filter has |H| = 1/2, i.e. −6.02 dB, at exactly the same
frequencies, and an effective roll-off of a sixth-order filter. The cut-off frequencies reported in
the methods are therefore the −6 dB points of the filter actually applied.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy import signal as sps

from bowden.analysis.emg._kernels import sliding_rms_rows
from bowden.analysis.emg.signal import EmgSignal
from bowden.analysis.emg.zero_phase import zero_phase_bandpass
from bowden.errors import ParameterError, RecordingError


def butterworth_bandpass_sos(
    rate_hz: float, *, low_hz: float = 20.0, high_hz: float = 400.0, order: int = 3
) -> NDArray[np.float64]:
    """Second-order sections of a digital Butterworth band-pass (single pass, −3 dB at the edges).

    Parameters
    ----------
    rate_hz
        Sampling rate, Hz.
    low_hz, high_hz
        Band edges, Hz; need 0 < low_hz < high_hz < rate_hz / 2.
    order
        Order of the low-pass prototype (paper: 3); the band-pass has 2·order poles.
    """
    _check_band(rate_hz, low_hz, high_hz, order)
    sos = sps.butter(order, [low_hz, high_hz], btype="bandpass", fs=rate_hz, output="sos")
    return np.asarray(sos, dtype=np.float64)


def _check_band(rate_hz: float, low_hz: float, high_hz: float, order: int) -> None:
    if not (isinstance(order, int) and order >= 1):
        raise ParameterError(f"order must be a positive integer, got {order!r}")
    if not (math.isfinite(low_hz) and math.isfinite(high_hz) and 0.0 < low_hz < high_hz):
        raise ParameterError(f"need 0 < low_hz < high_hz, got low_hz={low_hz}, high_hz={high_hz}")
    if high_hz >= rate_hz / 2.0:
        raise ParameterError(
            f"high_hz ({high_hz} Hz) must be below the Nyquist frequency ({rate_hz / 2.0} Hz) of the signal"
        )


def emg_filter(emg: EmgSignal, *, low_hz: float = 20.0, high_hz: float = 400.0, order: int = 3) -> EmgSignal:
    """Zero-phase Butterworth band-pass of every channel (paper: order 3, 20–400 Hz).

    The filter runs forwards and backwards (as ``scipy.signal.sosfiltfilt``, odd padding; all
    channels in one compiled pass, :mod:`~bowden.analysis.emg.zero_phase`), so it adds
    no delay and its magnitude response is the square of the single-pass one: −6.02 dB at
    ``low_hz`` and ``high_hz``.

    Parameters
    ----------
    emg
        Raw EMG, V.
    low_hz, high_hz, order
        See :func:`butterworth_bandpass_sos`.

    Returns
    -------
    EmgSignal
        Filtered EMG, same shape, channels, rate and start.
    """
    return emg.with_values(band_passed(emg, low_hz=low_hz, high_hz=high_hz, order=order), adopt=True)


def band_passed(
    emg: EmgSignal, *, low_hz: float = 20.0, high_hz: float = 400.0, order: int = 3
) -> NDArray[np.float64]:
    """The samples of :func:`emg_filter`, as a new writable array (the pipeline edits it in place)."""
    _check_band(emg.rate_hz, low_hz, high_hz, order)
    try:
        filtered, finite = zero_phase_bandpass(emg.values, emg.rate_hz, low_hz, high_hz, order)
    except ValueError as exc:  # the only complaint: the record is shorter than the padding
        _require_finite(emg, "emg_filter")
        raise RecordingError(f"emg_filter: the EMG ({emg.n_samples} samples) is too short: {exc}") from None
    if not finite:
        _require_finite(emg, "emg_filter")
    return filtered


def emg_rectify(emg: EmgSignal) -> EmgSignal:
    """Full-wave rectification, |x| per sample."""
    return emg.with_values(np.abs(emg.values), adopt=True)


def emg_envelope(emg: EmgSignal, *, window_s: float = 0.1) -> EmgSignal:
    """Sliding root-mean-square envelope, centred window (paper: 100 ms; Burden et al. 2017).

    ``y[i] = sqrt(mean(x[j]**2))`` over the ``round(window_s·rate)`` samples centred on ``i`` (for an
    even count the window reaches one sample further back than forwards). Near the ends the window
    shrinks to the samples that exist, as MATLAB's ``movmean`` does, so the envelope keeps its length
    and is not biased towards zero. The RMS of a rectified signal equals that of the signal, so
    applying it after :func:`emg_rectify` (as the paper does) changes nothing. A unit-amplitude sine
    with an integer number of periods per window gives 1/√2 = 0.7071.

    Parameters
    ----------
    emg
        Band-passed (and usually rectified) EMG, V.
    window_s
        Window length, s; at least one sample.

    Returns
    -------
    EmgSignal
        Envelope, V, same shape, channels, rate and start.
    """
    if not (math.isfinite(window_s) and window_s > 0.0):
        raise ParameterError(f"window_s must be positive, got {window_s}")
    width = round(window_s * emg.rate_hz)
    if width < 1:
        raise ParameterError(f"window_s={window_s} s is shorter than one sample at {emg.rate_hz} Hz")
    # One compiled pass: running sums of x² in record order (float64 keeps the cancellation error
    # far below EMG noise for hour-long records), the finiteness check on the way.
    envelope = np.empty(emg.values.shape)  # from NumPy: huge pages, few page faults
    finite = sliding_rms_rows(np.ascontiguousarray(emg.values), width, envelope)
    if not finite:
        _require_finite(emg, "emg_envelope")
    return emg.with_values(envelope, adopt=True)


def _require_finite(emg: EmgSignal, step: str) -> None:
    if np.isfinite(emg.values).all():  # the usual case: one pass, no index arrays
        return
    bad_rows, bad_columns = np.nonzero(~np.isfinite(emg.values))
    if bad_rows.size:
        raise RecordingError(
            f"{step}: EMG channel {emg.channels[bad_columns[0]]!r} is not finite at sample "
            f"{int(bad_rows[0])}; "
            "run emg_check and remove or interpolate the gap first"
        )
