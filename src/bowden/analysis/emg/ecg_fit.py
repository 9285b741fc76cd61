"""The per-beat fit of the adaptive ECG template subtraction (see :mod:`bowden.analysis.emg.ecg`).

Alignment by cross-correlation and the search over QRS stretch variants, each with a least-squares
scale and offset per P/QRS/T section (Petersen et al. 2020, IEEE Access 8:30905), for
all beats and all variants at once:

- the shifts are scored by one product of the QRS templates with a sliding window view of the
  signal (no loop over lags);
- the QRS variants of every beat come from one PCHIP evaluation at the concatenated sample
  positions of all variants (their derivatives are computed once, not once per variant);
- the six sums each section's least-squares fit needs (n, Σt, Σt², Σy, Σty, Σy²) come from
  prefix sums: over the signal for Σy and Σy², over each template row for Σt, Σt² and Σty of the
  P and T sections (whose extent depends on the variant only through where they end), and from a
  segmented sum over the concatenated variants for the QRS section.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray
from scipy import sparse

from bowden.analysis.emg._ecg_kernels import fitted_artefact, qrs_variant_sums


@dataclass(frozen=True)
class BeatFit:
    """The fitted artefact of every beat, and what a gate needs to judge its sections.

    All grids are beats x offsets ``-half…half`` from the aligned R-peaks. ``index``: the sample
    index of every grid cell (clipped to the record), ``inside``: the cells inside their beat
    (beats do not overlap, so ``index[inside]`` holds each sample once); ``artefact``: the fitted
    artefact; ``template``: each beat's template row with its chosen QRS variant; ``sections``:
    boolean masks (P, QRS, T) of the cells inside the beat; ``sse``/``energy``: residual energy of
    each section's fit and its energy before subtraction (3 x beats), V²; ``section_of``: per
    (beat, offset) the section number 0/1/2 (3 outside the beat), to spread per-section decisions.
    """

    index: NDArray[np.int64]
    inside: NDArray[np.bool_]
    artefact: NDArray[np.float64]
    template: NDArray[np.float64]
    sections: tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]
    sse: NDArray[np.float64]
    energy: NDArray[np.float64]
    section_of: NDArray[np.int8]


def _prefix(band: NDArray[np.float64]) -> NDArray[np.float64]:
    """Prefix sums along the last axis with a leading 0 (entry k: sum of the first k columns)."""
    zeros = np.zeros((*band.shape[:-1], 1))
    return np.concatenate([zeros, np.cumsum(band, axis=-1)], axis=-1)


@dataclass(frozen=True)
class _QrsVariantGrid:
    """All QRS variants' sample offsets side by side and their PCHIP evaluation matrix.

    ``evaluate`` maps the flattened PPoly coefficients (4 powers x 2·qrs intervals) of a QRS
    template on the integer grid -qrs…qrs to its values at ``offsets·qrs/w`` of every variant:
    the cubic of the interval a point falls in, in powers of its distance from the interval's
    start (the PPoly convention of SciPy). Four non-zeros per row.
    """

    offsets: NDArray[np.int64]
    starts: NDArray[np.int64]
    evaluate: sparse.csr_matrix
    segment_sum: sparse.csr_matrix


@functools.lru_cache(maxsize=16)
def _qrs_variant_grid(qrs: int, stretch: int) -> _QrsVariantGrid:
    widths = qrs + np.arange(-stretch, stretch + 1)
    offsets = np.concatenate([np.arange(-w, w + 1) for w in widths])
    points = np.concatenate([np.arange(-w, w + 1) * (qrs / w) for w in widths]) + qrs
    interval = np.clip(np.floor(points).astype(np.int64), 0, 2 * qrs - 1)
    local = points - interval
    rows = np.repeat(np.arange(points.size), 4)
    columns = (np.arange(4)[np.newaxis, :] * 2 * qrs + interval[:, np.newaxis]).ravel()
    values = (local[:, np.newaxis] ** np.arange(3, -1, -1)[np.newaxis, :]).ravel()
    matrix = sparse.csr_matrix((values, (rows, columns)), shape=(points.size, 4 * 2 * qrs))
    starts = np.concatenate([[0], np.cumsum(2 * widths + 1)[:-1]]).astype(np.int64)
    variant = np.repeat(np.arange(widths.size), 2 * widths + 1)
    indicator = sparse.csr_matrix(
        (np.ones(offsets.size), (variant, np.arange(offsets.size))), shape=(widths.size, offsets.size)
    )
    return _QrsVariantGrid(offsets=offsets, starts=starts, evaluate=matrix, segment_sum=indicator)


def pchip_coefficients(y: NDArray[np.float64]) -> NDArray[np.float64]:
    """PPoly coefficients (4 x intervals x columns) of the PCHIP interpolant of ``y`` on x = 0, 1, 2, …

    ``PchipInterpolator(np.arange(len(y)), y, axis=0).c`` to the last bit (the same operations on
    a unit grid, where SciPy's divisions by the spacing are exact), without its input checks and
    axis moves, which cost more than the arithmetic for a few hundred short templates.
    """
    slope = y[1:] - y[:-1]  # Fritsch–Carlson slopes; SciPy divides by the spacing, 1
    sign = np.sign(slope)
    flat = (sign[1:] != sign[:-1]) | (slope[1:] == 0) | (slope[:-1] == 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        harmonic = (3.0 / slope[:-1] + 3.0 / slope[1:]) / 6.0  # weights 2h+h = 3 on a unit grid
    derivative = np.zeros_like(y)
    derivative[1:-1][~flat] = 1.0 / harmonic[~flat]
    derivative[0] = _pchip_end(slope[0], slope[1])
    derivative[-1] = _pchip_end(slope[-1], slope[-2])
    t = derivative[:-1] + derivative[1:] - 2 * slope
    return np.stack((t, slope - derivative[:-1] - t, derivative[:-1], y[:-1]))


def _pchip_end(m0: NDArray[np.float64], m1: NDArray[np.float64]) -> NDArray[np.float64]:
    """SciPy's one-sided, shape-preserving end derivative of PCHIP (Moler, pchiptx.m), unit grid."""
    d = (3.0 * m0 - m1) / 2.0
    wrong_sign = np.sign(d) != np.sign(m0)
    overshoot = (np.sign(m0) != np.sign(m1)) & (np.abs(d) > 3.0 * np.abs(m0))
    d[wrong_sign] = 0.0
    d[~wrong_sign & overshoot] = 3.0 * m0[~wrong_sign & overshoot]
    return d


def alignment_shifts(
    y: NDArray[np.float64],
    peaks: NDArray[np.int64],
    template: NDArray[np.float64],
    half: int,
    qrs: int,
    max_shift: int,
) -> NDArray[np.int64]:
    """Lag (samples) maximising the cross-correlation of each template's QRS with its beat.

    The QRS template is centred, so its product with a window equals its product with the
    centred window (the window's mean drops out): one sliding-window product scores every lag.
    """
    if max_shift == 0:
        return np.zeros(peaks.size, dtype=np.int64)
    q = template[:, half - qrs : half + qrs + 1]
    q = q - q.mean(axis=1, keepdims=True)
    span = np.arange(-qrs - max_shift, qrs + max_shift + 1)
    windows = sliding_window_view(y[peaks[:, np.newaxis] + span], 2 * qrs + 1, axis=1)
    score = np.einsum("bj,blj->bl", q, windows)
    return np.asarray(np.argmax(score, axis=1) - max_shift, dtype=np.int64)


def section_fit(
    sums: tuple[NDArray[np.float64], ...],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """LS scale a, offset b and residual energy of y ≈ a·t + b from (n, Σt, Σt², Σy, Σty, Σy²).

    A flat or empty template section gets a = 0 (the offset alone is fitted). Works elementwise
    on arrays of any shape.
    """
    n, st, stt, sy, sty, syy = sums
    det = n * stt - st * st
    ok = det > 1e-12 * np.maximum(n * stt, 1e-300)
    a = np.where(ok, (n * sty - st * sy) / np.where(ok, det, 1.0), 0.0)
    b = np.where(n > 0, (sy - a * st) / np.maximum(n, 1.0), 0.0)
    sse = np.maximum(syy - a * sty - b * sy, 0.0)
    return np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64), np.asarray(sse, dtype=np.float64)


def fit_beats(
    y: NDArray[np.float64],
    aligned: NDArray[np.int64],
    start: NDArray[np.int64],
    end: NDArray[np.int64],
    template: NDArray[np.float64],
    half: int,
    qrs: int,
    stretch: int,
) -> BeatFit:
    """Best stretched variant per beat (smallest residual energy) with per-section LS scale and offset.

    The QRS section of variant ``d`` covers offsets ``-(qrs+d)…qrs+d`` from the aligned R-peak and
    holds the template's QRS part resampled by PCHIP; the P section is the beat before it, the T
    section the beat after it, both with the template's own samples.
    """
    n_beats = aligned.size
    offsets = np.arange(-half, half + 1)
    lo = start - aligned  # first offset of each beat relative to its aligned R-peak
    hi = end - aligned  # one past the last offset
    index = np.clip(aligned[:, np.newaxis] + offsets, 0, y.size - 1)
    inside = (offsets >= lo[:, np.newaxis]) & (offsets < hi[:, np.newaxis])
    widths = qrs + np.arange(-stretch, stretch + 1)  # QRS half widths of the variants

    # The beat's samples and template on the grid, zero outside the beat, so that a sum over a
    # column range counts the beat's own cells only. Sums are taken per beat (not as differences
    # of prefix sums over the whole record), so a perfect fit leaves a residual of rounding size.
    yz = np.where(inside, y[index], 0.0)
    tz = np.where(inside, template, 0.0)
    # The P section of variant w is columns [0, half - w): a part no variant changes plus a band of
    # 2·stretch columns whose prefix sums give every variant's share; likewise the T section.
    outer = qrs + stretch

    def fixed_sums(columns: slice) -> NDArray[np.float64]:
        t, x = tz[:, columns], yz[:, columns]
        return np.stack(
            [
                inside[:, columns].sum(axis=1, dtype=np.float64),
                t.sum(axis=1),
                np.einsum("ij,ij->i", t, t),
                x.sum(axis=1),
                np.einsum("ij,ij->i", t, x),
                np.einsum("ij,ij->i", x, x),
            ]
        )

    p_fixed = fixed_sums(slice(0, half - outer))
    t_fixed = fixed_sums(slice(half + outer + 1, offsets.size))

    def band_prefix(columns: slice) -> NDArray[np.float64]:
        t, x = tz[:, columns], yz[:, columns]
        return _prefix(np.stack([inside[:, columns].astype(np.float64), t, t * t, x, t * x, x * x]))

    p_band = band_prefix(slice(half - outer, half - qrs + stretch))
    t_band = band_prefix(slice(half + qrs - stretch + 1, half + outer + 1))
    d = widths - qrs
    p_stack = p_fixed[:, :, np.newaxis] + p_band[:, :, stretch - d]
    t_stack = t_fixed[:, :, np.newaxis] + t_band[:, :, -1:] - t_band[:, :, d + stretch]
    p_sums, t_sums = tuple(p_stack), tuple(t_stack)

    # Every variant's QRS side by side (variants x beats layout): segment k holds offsets
    # -w_k…w_k, the template's QRS part at positions offset·qrs/w_k, evaluated for all beats from
    # the PCHIP coefficients and summed per segment in one compiled pass (the sparse products'
    # arithmetic, without their temporaries).
    grid = _qrs_variant_grid(qrs, stretch)
    qrs_part = template[:, half - qrs : half + qrs + 1].T
    coefficients = pchip_coefficients(qrs_part).reshape(4 * 2 * qrs, n_beats)
    evaluate = (grid.evaluate.indptr, grid.evaluate.indices, grid.evaluate.data)
    t_qrs, sums = qrs_variant_sums(y, aligned, grid.offsets, evaluate, coefficients, grid.starts)
    q_sums = (np.broadcast_to((2.0 * widths + 1.0), (n_beats, widths.size)), *(x.T for x in sums))
    fits = [section_fit(sums) for sums in (p_sums, q_sums, t_sums)]
    total = fits[0][2] + fits[1][2] + fits[2][2]
    best = np.argmin(total, axis=1)  # the first of equal minima, as a loop over variants keeps
    rows = np.arange(n_beats)
    width = widths[best]

    # Each beat's template row with its chosen QRS variant, the cells' sections and the artefact.
    values, section_of, artefact = fitted_artefact(
        template,
        t_qrs,
        grid.starts[best],
        width,
        inside,
        np.stack([fit[0][rows, best] for fit in fits]),
        np.stack([fit[1][rows, best] for fit in fits]),
        half,
        outer,
    )
    sse = np.stack([fit[2][rows, best] for fit in fits])
    energy = np.stack([sums[5][rows, best] for sums in (p_sums, q_sums, t_sums)])
    sections = (section_of == 0, section_of == 1, section_of == 2)
    return BeatFit(
        index=np.asarray(index, dtype=np.int64),
        inside=inside,
        artefact=artefact,
        template=values,
        sections=sections,
        sse=sse,
        energy=energy,
        section_of=section_of,
    )
