"""The EMG under an ECG artefact: its spectrum, a Wiener filter for templates, synthetic EMG.

Support for :mod:`bowden.analysis.emg.ecg`: the noise model is measured on the channel after plain
template subtraction; the templates are denoised with it (Wiener 1949) and synthetic EMG with its
spectrum feeds the bootstrap of the section gate (``ecg._search_penalty``).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import fft as sp_fft

from bowden.analysis.emg._noise_kernels import mean_power, noise_statistics, scale_beats


@dataclass(frozen=True)
class NoiseModel:
    """The EMG under the artefact, as the gate and the template denoising need it.

    ``power`` holds rfft bins of length ``nfft`` such that ``qᵀ·C·q ≈ Σ_full |Q_k|²·P_k / nfft``
    for any vector q of at most nfft/2 samples (C: covariance of the EMG), and ``beat_scale`` the
    variance of each beat relative to the channel's (the EMG follows the activation).
    """

    nfft: int
    power: NDArray[np.float64]
    beat_scale: NDArray[np.float64]

    @classmethod
    def of(
        cls, residual: NDArray[np.float64], start: NDArray[np.int64], end: NDArray[np.int64], width: int
    ) -> NoiseModel:
        """Estimate from a residual (the channel after plain template subtraction).

        Bartlett's method: the mean periodogram of non-overlapping segments of nfft/2 samples,
        whose expectation is the spectrum of the autocovariance under a triangular lag window of
        nfft/2 lags (never negative). The residual holds what the plain subtraction left of the
        ECG too, which errs on the side of more noise, i.e. of subtracting less.
        """
        nfft = 1 << math.ceil(math.log2(2 * width))  # rows of ``width`` never wrap onto themselves
        segment = nfft // 2
        count = max(1, residual.size // segment)
        # The segments (zero-padded, in a work buffer) and the energies in one pass over the residual.
        segments = _work_rows(count, nfft)
        energies, total = noise_statistics(residual, start, end, segments)
        spectra = sp_fft.rfft(segments, axis=1)
        power = mean_power(spectra) / min(segment, residual.size)
        channel_variance = total / residual.size if residual.size else 0.0  # np.mean(residual**2)
        beat_variance = energies / np.maximum(end - start, 1)
        scale = beat_variance / channel_variance if channel_variance > 0.0 else np.zeros(start.size)
        return cls(nfft=nfft, power=np.asarray(power, dtype=np.float64), beat_scale=scale)


def denoised_templates(template: NDArray[np.float64], noise: NoiseModel, n_beats: int) -> NDArray[np.float64]:
    """Templates through one Wiener filter: keep the frequencies where the heartbeat stands out.

    A template is the mean of ``n_beats`` beats, so it carries their EMG with 1/n_beats of its
    power spectrum ``P(f)``; a template row of ``width`` samples then holds ``width·P(f)/n_beats``
    of EMG per frequency bin. Against the mean power of the templates ``S(f)`` the Wiener gain is
    ``max(0, 1 − width·P(f) / (n_beats·S(f)))`` (Wiener 1949). The ECG after
    the EMG band-pass lies mostly below ~60 Hz and the EMG mostly above, so the gain removes
    most of the template's EMG and keeps the heartbeat, without a cut-off chosen by hand. ``P``
    is the :class:`NoiseModel`'s. The filter is zero-phase (a real gain applied to the spectrum).
    """
    width = template.shape[1]
    spectra = sp_fft.rfft(_zero_padded(template, noise.nfft), axis=1)
    template_power = mean_power(spectra)
    noise_power = width * noise.power / n_beats
    gain = np.maximum(0.0, 1.0 - noise_power / np.maximum(template_power, np.finfo(float).tiny))
    spectra *= gain
    filtered = sp_fft.irfft(spectra, noise.nfft, axis=1, overwrite_x=True)
    return np.asarray(filtered[:, :width], dtype=np.float64)


def synthetic_emg(
    noise: NoiseModel, n: int, start: NDArray[np.int64], end: NDArray[np.int64], rng: np.random.Generator
) -> NDArray[np.float64]:
    """Gaussian noise of ``n`` samples with the model's spectrum and each beat's variance, V.

    White noise shaped in the frequency domain by the square root of the model's spectrum
    (interpolated onto the record's frequency grid; a circular convolution, harmless for a
    stationary process), then scaled per beat by the square root of ``beat_scale``.
    """
    return shaped_emg(noise, n, start, end, white_spectrum(n, rng))


def white_spectrum(n: int, rng: np.random.Generator) -> NDArray[np.complex128]:
    """rfft of the white noise :func:`synthetic_emg` shapes: ``next_fast_len(n)`` standard normals."""
    return np.asarray(sp_fft.rfft(rng.standard_normal(sp_fft.next_fast_len(n, real=True))))


def shaped_emg(
    noise: NoiseModel,
    n: int,
    start: NDArray[np.int64],
    end: NDArray[np.int64],
    white: NDArray[np.complex128],
) -> NDArray[np.float64]:
    """:func:`synthetic_emg` from a given :func:`white_spectrum` (left unchanged)."""
    length = sp_fft.next_fast_len(n, real=True)
    model_frequency = np.arange(noise.power.size) / noise.nfft  # cycles per sample
    frequency = np.arange(white.size) / length
    spectrum = white * np.sqrt(np.interp(frequency, model_frequency, noise.power))
    out = np.asarray(sp_fft.irfft(spectrum, length, overwrite_x=True)[:n], dtype=np.float64)
    scale_beats(out, start, end, np.ascontiguousarray(noise.beat_scale, dtype=np.float64))
    return out


_PADDED = threading.local()
_PADDED_KEPT = 4 * 2**20  # values (32 MB): a few hundred beats' templates


def _zero_padded(rows: NDArray[np.float64], nfft: int) -> NDArray[np.float64]:
    """``rows`` (r x m, m ≤ nfft) zero-padded to r x nfft in this thread's work buffer.

    SciPy's FFT transforms a stack of rows in vector instructions, several rows at once (NumPy's
    one at a time, about 20 % slower here), but pads a stack by copying it into a fresh array:
    the padding is done here instead, in a buffer kept between calls (valid until the next call).
    """
    count, width = rows.shape
    padded = _work_rows(count, nfft)
    padded[:, :width] = rows
    padded[:, width:] = 0.0
    return padded


def _work_rows(count: int, nfft: int) -> NDArray[np.float64]:
    """A count x nfft view of this thread's work buffer (contents undefined; valid until the next call)."""
    buffer: NDArray[np.float64] | None = getattr(_PADDED, "buffer", None)
    if buffer is None or buffer.size < count * nfft:
        buffer = np.empty(count * nfft)
        if buffer.size <= _PADDED_KEPT:
            _PADDED.buffer = buffer
    return buffer[: count * nfft].reshape(count, nfft)
