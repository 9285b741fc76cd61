"""The per-beat fit of the adaptive ECG template subtraction (see :mod:`bowden.analysis.emg.ecg`).

Alignment by cross-correlation and the search over QRS stretch variants, each with a least-squares
scale and offset per P/QRS/T section (Petersen et al. 2020, IEEE Access 8:30905), for
all beats and all variants at once:

- the shifts are scored by the product of each centred QRS template with the beat at every lag;
- the QRS variants of every beat come from one PCHIP evaluation at the concatenated sample
  positions of all variants (their derivatives are computed once, not once per variant);
- the six sums each section's least-squares fit needs (n, Σt, Σt², Σy, Σty, Σy²) come, for the P
  and T sections (whose extent depends on the variant only through where they end), from a fixed
  part plus the prefix sums of the band where the variants differ, and from a segmented sum over
  the concatenated variants for the QRS section.

The loops are compiled (:mod:`bowden.analysis.emg._fit_kernels`, :mod:`bowden.analysis.emg._ecg_kernels`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from bowden.analysis.emg._fit_kernels import (
    ADD,
    CORRELATE,
    SUBTRACT,
    apply_fit,
    best_shifts,
    choose_variants,
    pchip_coefficients,
    qrs_variant_sums,
)


@dataclass(frozen=True)
class BeatFit:
    """The fitted artefact of every beat, and what a gate needs to judge its sections.

    Beat k is fitted around its aligned R-peak ``aligned[k]`` within its samples [start, end):
    ``template`` holds its template at offsets ``-half…half`` (the P and T sections' samples),
    ``qrs`` the chosen QRS variant at offsets ``-outer…outer`` (valid within ``±width``, the
    variant's half width), and ``scale``/``offset`` the least-squares fit of each section (P, QRS,
    T; 3 x beats); the artefact of a sample is ``scale·template + offset`` of its section.
    ``sse``/``energy``: residual energy of each section's fit and its energy before subtraction
    (3 x beats), V². The artefact is never stored as a grid: the methods recompute it per sample.
    """

    aligned: NDArray[np.int64]
    start: NDArray[np.int64]
    end: NDArray[np.int64]
    width: NDArray[np.int64]
    template: NDArray[np.float64]
    qrs: NDArray[np.float64]
    scale: NDArray[np.float64]
    offset: NDArray[np.float64]
    sse: NDArray[np.float64]
    energy: NDArray[np.float64]

    def _apply(
        self, mode: int, e: NDArray[np.float64], keep: NDArray[np.bool_], out: NDArray[np.float64]
    ) -> Any:
        fit = (
            self.aligned,
            self.start,
            self.end,
            self.width,
            self.template,
            self.qrs,
            self.scale,
            self.offset,
        )
        return apply_fit(mode, e, *fit, keep, out)

    def subtracted_from(self, y: NDArray[np.float64], keep: NDArray[np.bool_]) -> NDArray[np.float64]:
        """A copy of ``y`` without the artefact of the sections kept (``keep``: 3 x beats)."""
        cleaned = y.copy()  # NumPy's allocation (huge pages), filled by the kernel
        self._apply(SUBTRACT, y, keep, cleaned)
        return cleaned

    def added_to(self, e: NDArray[np.float64]) -> NDArray[np.float64]:
        """A copy of the record ``e`` with every beat's fitted artefact added (all sections)."""
        record = e.copy()
        self._apply(ADD, e, _NO_SECTIONS, record)
        return record

    def products(self, e: NDArray[np.float64]) -> NDArray[np.float64]:
        """Σ artefact·e over each section of each beat (3 x beats), ``e`` a record."""
        return np.asarray(self._apply(CORRELATE, e, _NO_SECTIONS, e), dtype=np.float64)


_NO_SECTIONS = np.zeros((3, 0), dtype=np.bool_)  # ``keep`` where the mode does not read it


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
    centred window (the window's mean drops out): the product alone scores every lag.
    """
    if max_shift == 0:
        return np.zeros(peaks.size, dtype=np.int64)
    qrs_templates = np.ascontiguousarray(template[:, half - qrs : half + qrs + 1])
    return np.asarray(best_shifts(y, peaks, qrs_templates, max_shift), dtype=np.int64)


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
    section the beat after it, both with the template's own samples. ``template`` is beats x
    (2·half + 1), offsets ``-half…half``.
    """
    template = np.ascontiguousarray(template, dtype=np.float64)
    # Every variant's QRS side by side (variants x beats layout): segment k holds offsets
    # -w_k…w_k, the template's QRS part at positions offset·qrs/w_k, evaluated for all beats from
    # the PCHIP coefficients and summed per segment in one compiled pass.
    grid = _qrs_variant_grid(qrs, stretch)
    # Contiguous: a transposed slice's layout (C, F or neither, with the number of beats) would
    # compile the kernel once per layout.
    qrs_part = np.ascontiguousarray(template[:, half - qrs : half + qrs + 1].T)
    coefficients = pchip_coefficients(qrs_part).reshape(4 * 2 * qrs, aligned.size)
    evaluate = (grid.evaluate.indptr, grid.evaluate.indices, grid.evaluate.data)
    q_sums = qrs_variant_sums(y, aligned, grid.offsets, evaluate, coefficients, grid.starts)
    best, scale, offset, sse, energy, qrs_values = choose_variants(
        y, aligned, start, end, template, qrs, stretch, q_sums, evaluate, coefficients, grid.starts
    )
    return BeatFit(
        aligned=aligned,
        start=start,
        end=end,
        width=np.asarray(qrs - stretch + best, dtype=np.int64),
        template=template,
        qrs=qrs_values,
        scale=scale,
        offset=offset,
        sse=sse,
        energy=energy,
    )
