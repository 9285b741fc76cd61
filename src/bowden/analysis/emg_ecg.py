"""ECG artefact removal from EMG by template subtraction, plain or adaptive.

Written from the description of the adaptive template subtraction of Petersen E., Sauer J.,
Graßhoff J., Rostalski P. (2020) "Removing cardiac artifacts from single-channel respiratory
electromyograms", IEEE Access 8:30905–30917 (REFERENCE §5), not from its toolbox's code:

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
parameters and the best of 21 shifts x 21 stretches, and its 40-beat template carries 1/40 of the
neighbours' EMG power: on pure EMG without any ECG this removes about 1 % of the EMG energy
(−19 dB). Once the ECG is more than ~13 dB below the EMG, that is more than the ECG it removes, and
a plain 30 Hz high-pass did better (tests/analysis/test_emg_ecg.py tabulates the numbers):

7. *template denoising*: each template passes through one Wiener filter whose noise spectrum is the
   EMG's, measured on the channel (:func:`_denoised_templates`);
8. *section gate*: a section's fit is subtracted only where it lowers the expected error of the
   cleaned signal, judged by Mallows' Cp with the EMG's own covariance (:func:`_cp_gate`).

The residual energy of every variant comes from prefix sums of the P/T sections (which do not
depend on the variant except through where they end) plus the QRS section, so 21 variants cost
little more than one. ``method="template"`` is the plain template subtraction: the same moving
40-beat template, subtracted at the detected R-peaks without alignment, stretching, scaling,
denoising or gate. Beats whose QRS window does not fit inside the record are left untouched.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import fft as sp_fft
from scipy.interpolate import PchipInterpolator

from bowden.analysis.emg_signal import EmgSignal
from bowden.errors import ParameterError, RecordingError

EcgMethod = Literal["adaptive", "template"]
_MAX_HALF_BEAT_S = 1.0  # beyond 1 s from an R-peak nothing of the heartbeat is left to remove


@dataclass(frozen=True, kw_only=True)
class EcgRemovalParameters:
    """Settings of :func:`emg_remove_ecg` (defaults: REFERENCE §5, Petersen et al. 2020).

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
        Algorithm settings; defaults reproduce REFERENCE §5.

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
    # A contiguous copy: a column of a (samples x channels) array is strided, and the gathers
    # below would touch every channel's memory.
    y = np.ascontiguousarray(samples, dtype=np.float64)
    n = y.size
    qrs = max(1, round(params.qrs_half_width_s * rate_hz))
    # A QRS section must keep at least one sample per side whatever the stretch.
    stretch = max(0, min(params.stretch_samples, qrs - 1)) if params.method == "adaptive" else 0
    shift = params.max_shift_samples if params.method == "adaptive" else 0
    reach = qrs + stretch + shift
    peaks = r_peaks[(r_peaks - reach >= 0) & (r_peaks + reach < n)]
    if peaks.size < 2:
        return y.copy()
    start, end = _beat_bounds(peaks, n, round(_MAX_HALF_BEAT_S * rate_hz))
    half = int(max(np.max(peaks - start), np.max(end - 1 - peaks))) + shift
    half = max(half, qrs + stretch + 1)  # the grid always holds every QRS variant
    offsets = np.arange(-half, half + 1)
    template = _moving_templates(y, peaks, start, end, offsets, params.template_beats)
    if params.method == "template":
        return _subtract_plain(y, peaks, start, end, template, half)
    noise: _NoiseModel | None = None
    if params.denoise_template or params.gate:
        plain = _subtract_plain(y, peaks, start, end, template, half)
        noise = _NoiseModel.of(plain, start, end, offsets.size)
    if noise is not None and params.denoise_template:
        template = _denoised_templates(template, noise, params.template_beats)
    aligned = peaks + _alignment_shifts(y, peaks, template, half, qrs, shift)
    gate = noise if params.gate else None
    where, artefact = _fit_adaptive(y, aligned, start, end, template, half, qrs, stretch, gate)
    cleaned = y.copy()
    cleaned[where] -= artefact
    return cleaned


def _subtract_plain(
    y: NDArray[np.float64],
    peaks: NDArray[np.int64],
    start: NDArray[np.int64],
    end: NDArray[np.int64],
    template: NDArray[np.float64],
    half: int,
) -> NDArray[np.float64]:
    """``y`` minus each beat's template placed at its R-peak (the plain template subtraction)."""
    offsets = np.arange(-half, half + 1)
    inside = (offsets >= (start - peaks)[:, np.newaxis]) & (offsets < (end - peaks)[:, np.newaxis])
    cleaned = y.copy()
    # Beats do not overlap, so every index appears once and a fancy-indexed subtraction is exact.
    cleaned[(peaks[:, np.newaxis] + offsets)[inside]] -= template[inside]
    return cleaned


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
    index = peaks[:, np.newaxis] + offsets
    inside = (index >= start[:, np.newaxis]) & (index < end[:, np.newaxis])
    beats = np.where(inside, y[np.clip(index, 0, y.size - 1)], 0.0)
    # Moving sums over the beat axis through prefix sums; window [k - n//2, k + n - n//2].
    sums = np.vstack([np.zeros(offsets.size), np.cumsum(beats, axis=0)])
    counts = np.vstack([np.zeros(offsets.size), np.cumsum(inside, axis=0)])
    k = np.arange(peaks.size)
    lo = np.clip(k - n_beats // 2, 0, peaks.size)
    hi = np.clip(k + (n_beats - n_beats // 2) + 1, 0, peaks.size)
    total = sums[hi] - sums[lo] - beats
    count = counts[hi] - counts[lo] - inside
    return np.asarray(np.divide(total, count, out=np.zeros_like(total), where=count > 0), dtype=np.float64)


def _alignment_shifts(
    y: NDArray[np.float64],
    peaks: NDArray[np.int64],
    template: NDArray[np.float64],
    half: int,
    qrs: int,
    max_shift: int,
) -> NDArray[np.int64]:
    """Lag (samples) maximising the cross-correlation of each template's QRS with its beat."""
    if max_shift == 0:
        return np.zeros(peaks.size, dtype=np.int64)
    q = template[:, half - qrs : half + qrs + 1]
    q = q - q.mean(axis=1, keepdims=True)
    lags = np.arange(-max_shift, max_shift + 1)
    score = np.empty((peaks.size, lags.size))
    for j, lag in enumerate(lags):
        segment = y[(peaks + lag)[:, np.newaxis] + np.arange(-qrs, qrs + 1)]
        score[:, j] = np.sum(q * (segment - segment.mean(axis=1, keepdims=True)), axis=1)
    return np.asarray(lags[np.argmax(score, axis=1)], dtype=np.int64)


def _fit_adaptive(
    y: NDArray[np.float64],
    aligned: NDArray[np.int64],
    start: NDArray[np.int64],
    end: NDArray[np.int64],
    template: NDArray[np.float64],
    half: int,
    qrs: int,
    stretch: int,
    gate: _NoiseModel | None,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Best stretched variant per beat with per-section LS scale and offset.

    Returns the sample indices of every beat's samples and the fitted artefact at those samples
    (beats do not overlap, so each index appears once).
    """
    n_beats = aligned.size
    lo = start - aligned  # first offset of each beat relative to its aligned R-peak
    hi = end - aligned  # one past the last offset
    offsets = np.arange(-half, half + 1)
    index = np.clip(aligned[:, np.newaxis] + offsets, 0, y.size - 1)
    inside = (offsets >= lo[:, np.newaxis]) & (offsets < hi[:, np.newaxis])
    ys = np.where(inside, y[index], 0.0)
    ts = np.where(inside, template, 0.0)
    # Sums of 1, t, t², y, t·y, y² per beat over column slices (t and y are 0 outside the beat).
    # The P section of variant d is [lo, -(qrs+d)): a part that no variant touches,
    # [lo, -(qrs+stretch)), plus a narrow band whose prefix sums give every variant's share;
    # likewise the T section (qrs+d, hi). No full-width cumulative sums are needed.
    quantities = (inside.astype(np.float64), ts, ts * ts, ys, ts * ys, ys * ys)

    def column_sums(first: int, stop: int) -> NDArray[np.float64]:
        return np.stack([q[:, first:stop].sum(axis=1) for q in quantities])

    def band_prefix(first: int, stop: int) -> NDArray[np.float64]:
        band = np.stack([q[:, first:stop] for q in quantities])
        return np.concatenate([np.zeros((6, n_beats, 1)), np.cumsum(band, axis=2)], axis=2)

    outer = qrs + stretch
    p_fixed = column_sums(0, half - outer)
    t_fixed = column_sums(half + outer + 1, offsets.size)
    p_band = band_prefix(half - outer, half - qrs + stretch)  # offsets -(qrs+S) … -(qrs-S)-1
    t_band = band_prefix(half + qrs - stretch + 1, half + outer + 1)  # offsets qrs-S+1 … qrs+S
    t_band_total = t_band[:, :, -1]

    base_qrs = PchipInterpolator(np.arange(-qrs, qrs + 1), template[:, half - qrs : half + qrs + 1], axis=1)
    best_width = np.full(n_beats, qrs)
    best_fit = np.zeros((6, n_beats))  # scale and offset of the P, QRS and T sections
    best_sse = np.full(n_beats, np.inf)
    section_sse = np.zeros((3, n_beats))  # residual energy of each section's fit, V²
    section_energy = np.zeros((3, n_beats))  # energy of each section before any subtraction, V²
    variants: dict[int, NDArray[np.float64]] = {}
    for d in range(-stretch, stretch + 1):
        width = qrs + d
        qrs_offsets = np.arange(-width, width + 1)
        t_qrs = np.asarray(base_qrs(qrs_offsets * (qrs / width)), dtype=np.float64)
        variants[width] = t_qrs
        y_qrs = y[aligned[:, np.newaxis] + qrs_offsets]
        qrs_sums = np.stack(
            [
                np.full(n_beats, float(qrs_offsets.size)),
                t_qrs.sum(1),
                (t_qrs**2).sum(1),
                y_qrs.sum(1),
                (t_qrs * y_qrs).sum(1),
                (y_qrs**2).sum(1),
            ]
        )
        sums = (
            p_fixed + p_band[:, :, stretch - d],
            qrs_sums,
            t_fixed + t_band_total - t_band[:, :, d + stretch],
        )
        fits = [_section_fit(section) for section in sums]
        sse = fits[0][2] + fits[1][2] + fits[2][2]
        better = sse < best_sse
        if not np.any(better):
            continue
        best_sse[better] = sse[better]
        best_width[better] = width
        for section, (scale, offset, residual) in enumerate(fits):
            best_fit[2 * section, better] = scale[better]
            best_fit[2 * section + 1, better] = offset[better]
            section_sse[section, better] = residual[better]
            section_energy[section, better] = sums[section][5][better]
    # The chosen QRS variant of each beat, written into its template row (only the QRS columns).
    values = ts.copy()
    for width, t_qrs in variants.items():
        chosen = np.flatnonzero(best_width == width)
        if chosen.size:
            values[chosen, half - width : half + width + 1] = t_qrs[chosen]
    w = best_width[:, np.newaxis]
    in_p = offsets < -w
    in_t = offsets > w
    scale = np.where(in_p, best_fit[0][:, None], np.where(in_t, best_fit[4][:, None], best_fit[2][:, None]))
    offset = np.where(in_p, best_fit[1][:, None], np.where(in_t, best_fit[5][:, None], best_fit[3][:, None]))
    artefact = scale * values + offset
    if gate is not None:
        sections = (in_p & inside, ~in_p & ~in_t & inside, in_t & inside)
        keep = _cp_gate(gate, values, sections, section_sse, section_energy)
        artefact *= np.where(in_p, keep[0][:, None], np.where(in_t, keep[2][:, None], keep[1][:, None]))
    return np.asarray(index[inside], dtype=np.int64), np.asarray(artefact[inside], dtype=np.float64)


@dataclass(frozen=True)
class _NoiseModel:
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
    ) -> _NoiseModel:
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


def _denoised_templates(
    template: NDArray[np.float64], noise: _NoiseModel, n_beats: int
) -> NDArray[np.float64]:
    """Templates through one Wiener filter: keep the frequencies where the heartbeat stands out.

    A template is the mean of ``n_beats`` beats, so it carries their EMG with 1/n_beats of its
    power spectrum ``P(f)``; a template row of ``width`` samples then holds ``width·P(f)/n_beats``
    of EMG per frequency bin. Against the mean power of the templates ``S(f)`` the Wiener gain is
    ``max(0, 1 − width·P(f) / (n_beats·S(f)))`` (Wiener 1949). The ECG after
    the EMG band-pass lies mostly below ~60 Hz and the EMG mostly above, so the gain removes
    most of the template's EMG and keeps the heartbeat, without a cut-off chosen by hand. ``P``
    is the :class:`_NoiseModel`'s. The filter is zero-phase (a real gain applied to the spectrum).
    """
    width = template.shape[1]
    spectra = sp_fft.rfft(template, noise.nfft, axis=1)
    template_power = np.mean(spectra.real**2 + spectra.imag**2, axis=0)
    noise_power = width * noise.power / n_beats
    gain = np.maximum(0.0, 1.0 - noise_power / np.maximum(template_power, np.finfo(float).tiny))
    return np.asarray(sp_fft.irfft(spectra * gain, noise.nfft, axis=1)[:, :width], dtype=np.float64)


def _cp_gate(
    noise: _NoiseModel,
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

    ``C`` is the :class:`_NoiseModel`'s: the channel's spectrum after plain template subtraction,
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


def _section_fit(
    sums: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """LS scale a, offset b and residual energy of y ≈ a·t + b from (n, Σt, Σt², Σy, Σty, Σy²).

    A flat or empty template section gets a = 0 (the offset alone is fitted).
    """
    n, st, stt, sy, sty, syy = sums
    det = n * stt - st * st
    ok = det > 1e-12 * np.maximum(n * stt, 1e-300)
    a = np.where(ok, (n * sty - st * sy) / np.where(ok, det, 1.0), 0.0)
    b = np.where(n > 0, (sy - a * st) / np.maximum(n, 1.0), 0.0)
    sse = np.maximum(syy - a * sty - b * sy, 0.0)
    return np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64), np.asarray(sse, dtype=np.float64)
