"""R-peak detection in ECG-contaminated EMG (Pan & Tompkins 1985, adapted to sEMG).

Used by the ECG removal of :mod:`bowden.analysis.emg.ecg` (Petersen et al. 2020, IEEE Access 8:30905:
R-peaks at least 300 ms apart, found on a high-passed copy or on a cleaner channel). The detector works
on a band-passed copy of the raw channel: the high-pass removes baseline drift and movement artefacts,
the low-pass keeps the QRS complex (most of its energy lies in 5–30 Hz) while suppressing most of the
EMG (50–150 Hz).

Steps, after Pan J., Tompkins W.J. (1985) "A real-time QRS detection algorithm", IEEE Trans Biomed
Eng 32(3):230–236: derivative, squaring, moving-window integration (150 ms), candidate peaks at least
the refractory interval apart, adaptive signal/noise levels with threshold NPKI + ¼(SPKI − NPKI), and
a search-back with half the threshold when no beat was found for 1.66 mean RR intervals. Each
accepted beat is finally placed on the extremum of the band-passed copy (the R wave), with the
polarity that the majority of beats shows. Last, a plausibility check in the spirit of Pan & Tompkins'
T-wave discrimination: of two beats closer than a fraction of the median RR interval (default 0.6),
the one less like the median beat (correlation over ±100 ms of the copy) is dropped. Strong EMG bursts
otherwise pass as beats (measured on the tests' synthetic signals at 1 mV EMG RMS against a 1 mV R
wave: 4–7 false beats in 47–48 before, 0–1 after); a beat that early is not one template subtraction
could remove anyway.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy import signal as sps

from bowden.analysis.emg._rpeak_kernels import adaptive_threshold, integrated_energy
from bowden.analysis.emg.signal import EmgSignal
from bowden.analysis.emg.zero_phase import zero_phase_bandpass_columns
from bowden.errors import ParameterError

_INTEGRATION_WINDOW_S = 0.150  # Pan & Tompkins: about the widest QRS
_LEARNING_S = 2.0  # initial signal/noise levels from the first two seconds
_SEARCH_BACK_RR_FACTOR = 1.66  # Pan & Tompkins' RR-missed limit
_REFINE_HALF_WIDTH_S = 0.075  # R wave search around the integrated peak
_SHAPE_HALF_WIDTH_S = 0.100  # the QRS complex and its neighbourhood, for the shape comparison


def _checked_band(band_hz: tuple[float, float], rate_hz: float) -> tuple[float, float]:
    low_hz, high_hz = band_hz
    if not (0.0 < low_hz < high_hz < rate_hz / 2.0):
        raise ParameterError(f"band_hz must satisfy 0 < low < high < Nyquist, got {band_hz} at {rate_hz} Hz")
    return low_hz, high_hz


def emg_detect_r_peaks(
    emg: EmgSignal,
    *,
    channel: str | None = None,
    min_rr_s: float = 0.3,
    band_hz: tuple[float, float] = (5.0, 30.0),
    min_rr_fraction: float = 0.6,
) -> NDArray[np.int64]:
    """Sample indices of the R-peaks of the ECG that contaminates an EMG channel.

    Parameters
    ----------
    emg
        Raw (not yet 20 Hz high-passed) EMG or ECG, V; the QRS energy below 20 Hz is what the
        detector uses, so pass the raw channel rather than the 20–400 Hz band-passed one.
    channel
        Channel to detect on: a contaminated muscle or a cleaner reference (an ECG lead). ``None``
        requires a single-channel signal.
    min_rr_s
        Refractory interval: two R-peaks are never closer than this, s (Petersen et al. 2020: 300 ms).
    band_hz
        Pass band of the detection copy, Hz.
    min_rr_fraction
        Of two beats closer than this fraction of the median RR interval, the one less like the
        median beat is dropped; 0 keeps every beat the threshold accepted.

    Returns
    -------
    numpy.ndarray
        Increasing sample indices (int64) into ``emg``; empty when no heartbeat is found.
    """
    if channel is None:
        if len(emg.channels) != 1:
            raise ParameterError(f"channel is required for a signal with channels {list(emg.channels)}")
        channel = emg.channels[0]
    found = r_peaks_of_channels(
        emg, (channel,), min_rr_s=min_rr_s, band_hz=band_hz, min_rr_fraction=min_rr_fraction
    )
    return found[channel]


def r_peaks_of_channels(
    emg: EmgSignal,
    channels: tuple[str, ...],
    *,
    min_rr_s: float = 0.3,
    band_hz: tuple[float, float] = (5.0, 30.0),
    min_rr_fraction: float = 0.6,
) -> dict[str, NDArray[np.int64]]:
    """:func:`emg_detect_r_peaks` on several channels, their detection copies filtered in one pass."""
    if not (math.isfinite(min_rr_s) and min_rr_s > 0.0):
        raise ParameterError(f"min_rr_s must be positive, got {min_rr_s}")
    if not (math.isfinite(min_rr_fraction) and 0.0 <= min_rr_fraction < 1.0):
        raise ParameterError(f"min_rr_fraction must be in [0, 1), got {min_rr_fraction}")
    rate = emg.rate_hz
    for name in channels:
        emg.channel(name)  # a RecordingError naming a missing channel
    low_hz, high_hz = _checked_band(band_hz, rate)
    columns = [emg.channels.index(name) for name in channels]
    # The detection copies (each channel band-passed at band_hz, 2nd order, zero-phase), one contiguous
    # row per channel.
    copies = zero_phase_bandpass_columns(emg.values, columns, rate, low_hz, high_hz, 2)
    refractory = max(1, round(min_rr_s * rate))
    found: dict[str, NDArray[np.int64]] = {}
    for k, name in enumerate(channels):
        copy = copies[k]
        feature = integrated_energy(copy, max(1, round(_INTEGRATION_WINDOW_S * rate)), rate)
        candidates, _ = sps.find_peaks(feature, distance=refractory)
        if candidates.size == 0:
            found[name] = np.empty(0, dtype=np.int64)
            continue
        beats = _adaptive_threshold(candidates, feature[candidates], rate, refractory)
        refined = _refine_to_r_wave(copy, beats, rate, refractory)
        found[name] = _drop_early_misfits(copy, refined, rate, min_rr_fraction)
    return found


def _adaptive_threshold(
    candidates: NDArray[np.intp], heights: NDArray[np.float64], rate_hz: float, refractory: int
) -> NDArray[np.intp]:
    """Pan–Tompkins signal/noise level tracking with search-back, on integrated-energy peaks."""
    learning = candidates < candidates[0] + int(_LEARNING_S * rate_hz)
    signal_level = 0.5 * float(np.max(heights[learning]))
    noise_level = 0.5 * float(np.mean(heights[learning]))
    beats = adaptive_threshold(
        candidates.astype(np.int64),
        np.ascontiguousarray(heights, dtype=np.float64),
        signal_level,
        noise_level,
        refractory,
        _SEARCH_BACK_RR_FACTOR,
    )
    return beats.astype(np.intp)


def _refine_to_r_wave(
    copy: NDArray[np.float64], beats: NDArray[np.intp], rate_hz: float, refractory: int
) -> NDArray[np.int64]:
    """Move each beat to the R-wave extremum of the detection copy, majority polarity."""
    if beats.size == 0:
        return np.empty(0, dtype=np.int64)
    half = max(1, round(_REFINE_HALF_WIDTH_S * rate_hz))
    offsets = np.arange(-half, half + 1)
    windows = np.clip(beats[:, np.newaxis] + offsets, 0, copy.size - 1)
    segments = copy[windows]
    extreme = segments[np.arange(beats.size), np.argmax(np.abs(segments), axis=1)]
    polarity = 1.0 if np.sum(extreme > 0.0) >= np.sum(extreme < 0.0) else -1.0
    refined = windows[np.arange(beats.size), np.argmax(polarity * segments, axis=1)]
    refined = np.unique(refined)
    # Two integrated peaks can refine onto nearby samples: keep the taller of any pair too close.
    keep: list[int] = []
    for position in refined:
        if keep and position - keep[-1] < refractory:
            if polarity * copy[position] > polarity * copy[keep[-1]]:
                keep[-1] = int(position)
            continue
        keep.append(int(position))
    return np.asarray(keep, dtype=np.int64)


def _drop_early_misfits(
    copy: NDArray[np.float64], beats: NDArray[np.int64], rate_hz: float, min_rr_fraction: float
) -> NDArray[np.int64]:
    """Of each pair of beats closer than ``min_rr_fraction`` median RR, drop the one least like the rest."""
    half = max(1, round(_SHAPE_HALF_WIDTH_S * rate_hz))
    offsets = np.arange(-half, half + 1)
    while beats.size >= 4 and min_rr_fraction > 0.0:
        rr = np.diff(beats)
        close = np.nonzero(rr < min_rr_fraction * float(np.median(rr)))[0]
        if close.size == 0:
            break
        # Likeness to the median beat (robust to the few false ones), recomputed after every drop so
        # that the template and the median interval sharpen as the false beats go.
        windows = copy[np.clip(beats[:, np.newaxis] + offsets, 0, copy.size - 1)]
        windows = windows - windows.mean(axis=1, keepdims=True)
        template = np.median(windows, axis=0)
        norms = np.linalg.norm(windows, axis=1) * np.linalg.norm(template)
        likeness = (windows @ template) / np.where(norms > 0.0, norms, 1.0)
        i = int(close[np.argmin(np.minimum(likeness[close], likeness[close + 1]))])
        beats = np.delete(beats, i if likeness[i] < likeness[i + 1] else i + 1)
    return beats
