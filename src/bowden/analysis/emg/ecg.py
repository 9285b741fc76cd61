"""ECG artefact removal from EMG by template subtraction, plain or adaptive.

Written from the description of the adaptive template subtraction of Petersen E., Sauer J.,
Graßhoff J., Rostalski P. (2020) "Removing cardiac artifacts from single-channel respiratory
electromyograms", IEEE Access 8:30905–30917, not from its toolbox's code:

1. beats are cut at the midpoints between consecutive R-peaks;
2. the template of a beat is the mean of the ``template_beats`` (40) beats centred on it, aligned
   at their R-peaks (20 before and 20 after it; the beat itself is left out, see
   :func:`_moving_templates` for why);
3. the template is aligned to the beat by cross-correlation of its QRS part (R ± 55 ms);
4. the QRS part is stretched or shrunk by −10…+10 samples per side (21 variants, PCHIP
   resampling) while the P part (beat start to the QRS) and the T part (QRS to beat end) keep the
   template's samples;
5. each of the three sections gets its own least-squares scale and offset, and the variant with
   the smallest residual energy over the whole beat is kept;
6. the fitted artefact (scale · template + offset, per section) is subtracted.

Two additions to the description, both on by default and both switchable off
(:class:`EcgRemovalParameters`), because the fit above also fits EMG. Each beat gets 6 least-squares
parameters after the best of 21 shifts and then the best of 21 stretches, and its 40-beat template
carries 1/40 of the neighbours' EMG power: on pure EMG without any ECG the described algorithm
removes about 1 % of the EMG energy (−19 dB). Once the ECG is more than ~13 dB below the EMG, that
is more than the ECG it removes (tests/analysis/test_emg_ecg.py and docs/study.md tabulate it):

7. *template denoising*: each template passes through one Wiener filter whose noise spectrum is the
   EMG's, measured on the channel (:func:`~bowden.analysis.emg.ecg_noise.denoised_templates`);
8. *section gate*: a section's fit is subtracted only where it is expected to lower the error of
   the cleaned signal, by Mallows' Cp in Efron's covariance-penalty form with the search included
   (a parametric bootstrap, :func:`_search_penalty`), pooled per section type as a line in the
   beat's EMG variance (:func:`_pooled_gate`).

The fit itself (all beats, shifts and stretch variants at once) is
:mod:`bowden.analysis.emg.ecg_fit`. ``method="template"`` is the plain template subtraction: the same moving
40-beat template, subtracted at the detected R-peaks without alignment, stretching, scaling,
denoising or gate. Beats whose QRS window does not fit inside the record are left untouched.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bowden.analysis.emg._ecg_kernels import moving_templates, subtract_templates
from bowden.analysis.emg.ecg_fit import BeatFit, alignment_shifts, fit_beats
from bowden.analysis.emg.ecg_noise import NoiseModel, denoised_templates, shaped_emg, white_spectrum
from bowden.analysis.emg.signal import EmgSignal
from bowden.errors import ParameterError, RecordingError

EcgMethod = Literal["adaptive", "template"]
_MAX_HALF_BEAT_S = 1.0  # beyond 1 s from an R-peak nothing of the heartbeat is left to remove
_BOOTSTRAP_SEED = 20040601  # fixed: the same channel always gets the same gate
_BOOTSTRAP_DRAWS = 1
_BOOTSTRAP_BEATS = 32  # beats refitted per draw (the penalty is pooled over them)


@dataclass(frozen=True, kw_only=True)
class EcgRemovalParameters:
    """Settings of :func:`emg_remove_ecg` (defaults: Petersen et al. 2020).

    Parameters
    ----------
    method
        ``"adaptive"`` (aligned, stretched, per-section scaled template) or ``"template"`` (plain).
    template_beats
        Number of beats averaged into each beat's template, centred on it.
    qrs_half_width_s
        Half width of the QRS section around the R-peak, s (55 ms).
    stretch_samples
        The QRS part is stretched/shrunk by −n…+n samples per side (10 → 21 variants).
    max_shift_samples
        Largest cross-correlation shift when aligning the template to a beat, samples.
    gate
        Adaptive method only: subtract a section's fit only where it lowers the expected error
        of the cleaned signal (Mallows' Cp, see :func:`_cp_gate`); ``False`` subtracts every
        section, as the description of Petersen et al. does.
    denoise_template
        Adaptive method only: pass the templates through a Wiener filter estimated from the data
        (see :func:`_denoised_templates`) before aligning and fitting them; ``False`` uses the
        plain 40-beat means.
    """

    method: EcgMethod = "adaptive"
    template_beats: int = 40
    qrs_half_width_s: float = 0.055
    stretch_samples: int = 10
    max_shift_samples: int = 10
    gate: bool = True
    denoise_template: bool = True

    def __post_init__(self) -> None:
        if self.method not in ("adaptive", "template"):
            raise ParameterError(f"method must be 'adaptive' or 'template', got {self.method!r}")
        if not (isinstance(self.template_beats, int) and self.template_beats >= 1):
            raise ParameterError(f"template_beats must be a positive integer, got {self.template_beats!r}")
        if not (math.isfinite(self.qrs_half_width_s) and self.qrs_half_width_s > 0.0):
            raise ParameterError(f"qrs_half_width_s must be positive, got {self.qrs_half_width_s}")
        for flag in ("gate", "denoise_template"):
            if not isinstance(getattr(self, flag), bool):
                raise ParameterError(f"{flag} must be True or False, got {getattr(self, flag)!r}")
        for name in ("stretch_samples", "max_shift_samples"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 0):
                raise ParameterError(f"{name} must be a non-negative integer, got {value!r}")


def emg_remove_ecg(
    emg: EmgSignal,
    r_peaks: ArrayLike,
    *,
    channels: tuple[str, ...] | None = None,
    parameters: EcgRemovalParameters | None = None,
) -> EmgSignal:
    """Subtract the ECG artefact from the named channels of a band-passed EMG.

    Parameters
    ----------
    emg
        Band-passed EMG (the composer uses 20–400 Hz), V.
    r_peaks
        Increasing sample indices of the R-peaks in ``emg`` (see :func:`emg_detect_r_peaks`).
    channels
        Channels to clean; ``None`` cleans all. Other channels pass through unchanged.
    parameters
        Algorithm settings; defaults reproduce Petersen et al. 2020.

    Returns
    -------
    EmgSignal
        The EMG with the artefact subtracted from the chosen channels.
    """
    params = parameters or EcgRemovalParameters()
    peaks = np.asarray(r_peaks, dtype=np.int64).ravel()
    if peaks.size and (peaks[0] < 0 or peaks[-1] >= emg.n_samples or np.any(np.diff(peaks) <= 0)):
        raise RecordingError(f"r_peaks must be increasing sample indices within 0..{emg.n_samples - 1}")
    names = emg.channels if channels is None else channels
    cleaned = {
        name: remove_ecg_from_channel(np.asarray(emg.channel(name)), peaks, emg.rate_hz, params)
        for name in names
    }
    out = np.column_stack([cleaned.get(name, emg.values[:, i]) for i, name in enumerate(emg.channels)])
    return emg.with_values(out, adopt=True)


def remove_ecg_from_channel(
    samples: NDArray[np.float64], r_peaks: NDArray[np.int64], rate_hz: float, params: EcgRemovalParameters
) -> NDArray[np.float64]:
    """One channel of :func:`emg_remove_ecg` (1-D in, cleaned copy out)."""
    # A contiguous, writable copy: a column of a (samples x channels) array is strided, and the
    # gathers below would touch every channel's memory; numba types a read-only array apart, so a
    # read-only column (a one-channel EmgSignal's) compiled every kernel a second time (8 s of CPU).
    y = np.array(samples, dtype=np.float64, order="C")
    n = y.size
    qrs = max(1, round(params.qrs_half_width_s * rate_hz))
    # A QRS section must keep at least one sample per side whatever the stretch.
    stretch = max(0, min(params.stretch_samples, qrs - 1)) if params.method == "adaptive" else 0
    shift = params.max_shift_samples if params.method == "adaptive" else 0
    reach = qrs + stretch + shift
    peaks = r_peaks[(r_peaks - reach >= 0) & (r_peaks + reach < n)]
    if peaks.size < 2:
        return y
    start, end = _beat_bounds(peaks, n, round(_MAX_HALF_BEAT_S * rate_hz))
    half = int(max(np.max(peaks - start), np.max(end - 1 - peaks))) + shift
    half = max(half, qrs + stretch + 1)  # the grid always holds every QRS variant
    offsets = np.arange(-half, half + 1)
    template = _moving_templates(y, peaks, start, end, offsets, params.template_beats)
    if params.method == "template":
        return _subtract_plain(y, peaks, start, end, template, half)
    noise: NoiseModel | None = None
    if params.denoise_template or params.gate:
        plain = _subtract_plain(y, peaks, start, end, template, half)
        noise = NoiseModel.of(plain, start, end, offsets.size)
    if noise is not None and params.denoise_template:
        template = denoised_templates(template, noise, params.template_beats)

    def fit_to(signal: NDArray[np.float64], rows: NDArray[np.int64] | slice = slice(None)) -> BeatFit:
        aligned = peaks[rows] + alignment_shifts(signal, peaks[rows], template[rows], half, qrs, shift)
        return fit_beats(signal, aligned, start[rows], end[rows], template[rows], half, qrs, stretch)

    fit = fit_to(y)
    keep = np.ones((3, peaks.size), dtype=np.bool_)
    if noise is not None and params.gate:
        penalty = _search_penalty(fit, fit_to, noise, n, start, end)
        keep = _pooled_gate(fit.energy - fit.sse - 2.0 * penalty, noise.beat_scale)
    # Each sample of a kept section (per beat) loses its fitted artefact.
    return fit.subtracted_from(y, keep)


def _pooled_gate(gain: NDArray[np.float64], beat_scale: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Which sections to subtract (sections x beats): where the expected gain, pooled, is positive.

    ``gain = energy − sse − 2·penalty`` estimates, per beat and section, how much subtracting the
    fit lowers the error (:func:`_search_penalty`). Deciding on each beat's own estimate is a
    pre-test that itself favours the beats whose fit happened to catch EMG. The expected gain is
    the ECG energy the fit captures (about the same in every beat) minus a cost proportional to
    the beat's EMG variance, so per section type it is modelled as ``A − B·beat_scale`` and fitted
    by least squares over all beats: two parameters per section type and channel instead of one
    decision per beat. A section is subtracted where the fitted line is positive.
    """
    keep = np.empty(gain.shape, dtype=np.bool_)
    design = np.column_stack([np.ones_like(beat_scale), beat_scale])
    for section, row in enumerate(gain):
        if beat_scale.size < 4 or np.ptp(beat_scale) <= 0.0:
            keep[section] = np.mean(row) > 0.0
            continue
        coefficients = np.linalg.lstsq(design, row, rcond=None)[0]
        keep[section] = design @ coefficients > 0.0
    return keep


def _search_penalty(
    fit: BeatFit,
    fit_to: Callable[[NDArray[np.float64], NDArray[np.int64]], BeatFit],
    noise: NoiseModel,
    n: int,
    start: NDArray[np.int64],
    end: NDArray[np.int64],
) -> NDArray[np.float64]:
    """Covariance penalty of each section's fit, search included (sections x beats), V².

    Subtracting a section's fitted artefact ``ŷ`` changes the expected error of the cleaned signal
    by ``E[sse] − E[energy] + 2·Σ cov(ŷᵢ, eᵢ)`` (e: the EMG), so the fit pays iff
    ``sse + 2·Σ cov(ŷᵢ, eᵢ) < energy`` (Mallows' Cp in the covariance-penalty form of Efron 2004,
    JASA 99:619). For a fixed linear fit the covariance term is ``tr(C·H)``; here the fit also picks
    the best of the shifts and QRS stretches, which fits the EMG more and has no closed form (the
    "generalized degrees of freedom" of Ye 1998, JASA 93:120). It is estimated as Efron does, by a
    parametric bootstrap: the whole fit, alignment and stretch search included, is repeated on the
    fitted artefact plus synthetic EMG ``e*`` with the channel's spectrum and per-beat variance, and
    ``Σ ŷ*ᵢ·e*ᵢ`` per section is the estimate. One draw per beat is noisy, so the estimate is pooled
    over the beats per section type after dividing by each beat's EMG variance, and scaled back;
    being pooled, it needs only ``_BOOTSTRAP_BEATS`` beats spread over the record.
    """
    rows = np.unique(
        np.linspace(0, start.size - 1, min(start.size, _BOOTSTRAP_BEATS)).round().astype(np.int64)
    )
    scale = np.maximum(noise.beat_scale, np.finfo(float).tiny)
    pooled = np.zeros(3)
    for white in _bootstrap_white_spectra(n):
        emg = shaped_emg(noise, n, start, end, white)
        refit = fit_to(fit.added_to(emg), rows)  # the fitted artefact plus synthetic EMG
        pooled += np.mean(refit.products(emg) / scale[rows], axis=1)
    return np.asarray(pooled[:, np.newaxis] / _BOOTSTRAP_DRAWS * scale[np.newaxis, :], dtype=np.float64)


@functools.lru_cache(maxsize=2)
def _bootstrap_white_spectra(n: int) -> tuple[NDArray[np.complex128], ...]:
    """The bootstrap's white noise, one spectrum per draw, from the fixed seed.

    It depends on the record's length only, so the contaminated channels of a trial share it
    (drawn and transformed once per trial instead of once per channel).
    """
    rng = np.random.default_rng(_BOOTSTRAP_SEED)
    spectra = tuple(white_spectrum(n, rng) for _ in range(_BOOTSTRAP_DRAWS))
    for spectrum in spectra:
        spectrum.flags.writeable = False  # shared between calls
    return spectra


def _subtract_plain(
    y: NDArray[np.float64],
    peaks: NDArray[np.int64],
    start: NDArray[np.int64],
    end: NDArray[np.int64],
    template: NDArray[np.float64],
    half: int,
) -> NDArray[np.float64]:
    """``y`` minus each beat's template placed at its R-peak (the plain template subtraction)."""
    # Beats do not overlap, so every sample is changed at most once.
    return subtract_templates(y, peaks, start, end, template, half)


def _beat_bounds(
    peaks: NDArray[np.int64], n: int, max_half: int
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """[start, end) of each beat: RR midpoints, half the median RR at the record's ends."""
    mids = (peaks[:-1] + peaks[1:]) // 2
    edge = int(np.median(np.diff(peaks))) // 2
    start = np.concatenate([[peaks[0] - edge], mids])
    end = np.concatenate([mids, [peaks[-1] + edge + 1]])
    start = np.clip(np.maximum(start, peaks - max_half), 0, n)
    end = np.clip(np.minimum(end, peaks + max_half + 1), 0, n)
    return start.astype(np.int64), end.astype(np.int64)


def _moving_templates(
    y: NDArray[np.float64],
    peaks: NDArray[np.int64],
    start: NDArray[np.int64],
    end: NDArray[np.int64],
    offsets: NDArray[np.int64],
    n_beats: int,
) -> NDArray[np.float64]:
    """Template per beat: mean of the ``n_beats`` neighbouring beats centred on it, R-aligned.

    The beat itself is left out (n/2 beats before it, n/2 after, fewer at the record's ends).
    Including it would let the least-squares scale of the adaptive method fit the beat's own EMG,
    which sits in the template with weight 1/n: in sections where the band-passed ECG is small the
    fitted scale then tends to 1 and the template's averaged EMG (variance σ²/n) is subtracted
    everywhere. Without it the scale of an ECG-free section tends to 0 and leaves the EMG alone.
    """
    # Moving sums over the beat axis through running sums (one compiled pass, record order as
    # np.cumsum); window [k - n//2, k + n - n//2], minus the beat itself.
    out = np.empty((peaks.size, offsets.size))  # NumPy's allocation (huge pages), filled by the kernel
    moving_templates(y, peaks, start, end, int(offsets[0]), n_beats, out)
    return out
