"""The EMG under an ECG artefact: its spectrum, a Wiener filter for templates, a section gate.

Support for :mod:`bowden.analysis.emg_ecg`: the noise model is measured on the channel after plain
template subtraction; the templates are denoised with it (Wiener 1949) and a fitted section is
kept only where Mallows' Cp with the EMG's covariance says it pays (Mallows 1973).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import fft as sp_fft


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
        segments = np.resize(residual, count * segment).reshape(count, segment)
        if residual.size < segment:
            segments[0, residual.size :] = 0.0
        spectra = sp_fft.rfft(segments, nfft, axis=1)
        power = np.mean(spectra.real**2 + spectra.imag**2, axis=0) / min(segment, residual.size)
        channel_variance = float(np.mean(residual * residual))
        squares = np.concatenate([[0.0], np.cumsum(residual * residual)])
        beat_variance = (squares[end] - squares[start]) / np.maximum(end - start, 1)
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
    spectra = sp_fft.rfft(template, noise.nfft, axis=1)
    template_power = np.mean(spectra.real**2 + spectra.imag**2, axis=0)
    noise_power = width * noise.power / n_beats
    gain = np.maximum(0.0, 1.0 - noise_power / np.maximum(template_power, np.finfo(float).tiny))
    return np.asarray(sp_fft.irfft(spectra * gain, noise.nfft, axis=1)[:, :width], dtype=np.float64)


def cp_gate(
    noise: NoiseModel,
    template: NDArray[np.float64],
    sections: tuple[NDArray[np.bool_], ...],
    sse: NDArray[np.float64],
    energy: NDArray[np.float64],
) -> NDArray[np.bool_]:
    """Which beat sections (sections x beats) to subtract: those whose fit lowers Mallows' Cp.

    Subtracting a section's fit ``a·t + b`` changes the error of the cleaned signal (against the
    EMG ``e`` underneath) from ``|m|²`` (artefact ``m`` left in) to the misfit plus the part of
    the EMG that the fit takes away: the projection ``H·e`` of the EMG onto span{t, 1}. With ``C``
    the covariance of the EMG, E[energy] = |m|² + E|e|² and E[sse] = E[error after] + E|e|² −
    2·tr(C·H) (Mallows 1973, Technometrics 15:661, for correlated noise), so the fit helps in
    expectation iff ``sse + 2·tr(C·H) < energy``. For white EMG tr(C·H) is 2σ²; band-limited
    EMG concentrates its power, and a template that is mostly EMG (a P or T wave that the 20 Hz
    high-pass has flattened, averaged with the neighbours' EMG) takes away several times more:
    this is what made the ungated subtraction lose to a plain high-pass at high EMG levels.

    ``C`` is the :class:`NoiseModel`'s: the channel's spectrum after plain template subtraction,
    scaled per beat by the beat's variance.
    """
    n_beats = template.shape[0]
    weight = np.full(noise.power.size, 2.0)  # rfft bins stand for two bins of the full spectrum ...
    weight[0] = 1.0
    weight[-1] = 1.0  # ... except DC and Nyquist
    weighted_power = (weight * noise.power / noise.nfft).astype(np.float32)
    # The constant direction 1/√L of a run of L samples: qᵀCq = r(0) + (2/L)·Σ_{τ<L} (L − τ)·r(τ),
    # from prefix sums of the autocovariance r (no transform per beat).
    r = sp_fft.irfft(noise.power, noise.nfft)[: noise.nfft // 2]
    lag = np.arange(r.size)
    first_moment = np.concatenate([[0.0], np.cumsum(r[1:])])
    second_moment = np.concatenate([[0.0], np.cumsum(lag[1:] * r[1:])])
    penalty = np.zeros((len(sections), n_beats))
    for k, mask in enumerate(sections):
        count = np.maximum(mask.sum(axis=1), 1)
        last = np.minimum(count - 1, r.size - 1)
        penalty[k] = r[0] + 2.0 * (count * first_moment[last] - second_moment[last]) / count
        t = np.where(mask, template, 0.0)
        centred = np.where(mask, t - (t.sum(axis=1) / count)[:, np.newaxis], 0.0)
        norm = np.sqrt(np.sum(centred * centred, axis=1))
        # Single precision is plenty for a penalty and halves the cost of the transforms.
        unit = (centred / np.where(norm > 0.0, norm, 1.0)[:, np.newaxis]).astype(np.float32)
        spectra = sp_fft.rfft(unit, noise.nfft, axis=1)
        penalty[k] += (spectra.real**2 + spectra.imag**2) @ weighted_power
    return np.asarray(sse + 2.0 * penalty * noise.beat_scale < energy, dtype=np.bool_)


def synthetic_emg(
    noise: NoiseModel, n: int, start: NDArray[np.int64], end: NDArray[np.int64], rng: np.random.Generator
) -> NDArray[np.float64]:
    """Gaussian noise of ``n`` samples with the model's spectrum and each beat's variance, V.

    White noise shaped in the frequency domain by the square root of the model's spectrum
    (interpolated onto the record's frequency grid; a circular convolution, harmless for a
    stationary process), then scaled per beat by the square root of ``beat_scale``.
    """
    length = sp_fft.next_fast_len(n, real=True)
    spectrum = sp_fft.rfft(rng.standard_normal(length))
    model_frequency = np.arange(noise.power.size) / noise.nfft  # cycles per sample
    frequency = np.arange(spectrum.size) / length
    spectrum *= np.sqrt(np.interp(frequency, model_frequency, noise.power))
    out = np.asarray(sp_fft.irfft(spectrum, length)[:n], dtype=np.float64)
    gain = np.ones(n)
    for first, stop, scale in zip(start, end, noise.beat_scale, strict=True):
        gain[first:stop] = math.sqrt(max(float(scale), 0.0))
    out *= gain
    return out
