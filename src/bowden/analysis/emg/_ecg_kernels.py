"""Compiled loops of the ECG template subtraction (:mod:`bowden.analysis.emg.ecg`).

Each replaces a chain of NumPy operations over the beats x offsets grid (tens of full-size
temporaries per channel) by one pass with the same arithmetic in the same order, so the results are
those of the NumPy code to the last bit (tests/analysis/test_emg_pipeline_fixture.py pins them).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from bowden.analysis.emg._kernels import jit


@jit
def moving_templates(
    y: NDArray[np.float64],
    peaks: NDArray[np.int64],
    start: NDArray[np.int64],
    end: NDArray[np.int64],
    first_offset: int,
    width: int,
    n_beats: int,
) -> NDArray[np.float64]:
    """Each beat's template: mean of its ``n_beats`` neighbours (n//2 before, the rest after), not itself.

    Grid: beats x offsets ``first_offset … first_offset + width − 1`` from the R-peaks; a cell
    counts where its sample lies inside its beat [start, end). Sums over the beat axis come from
    running sums accumulated beat by beat (as ``np.cumsum(axis=0)``); a cell with no neighbour is 0.
    """
    count_beats = peaks.size
    sums = np.zeros((count_beats + 1, width))
    counts = np.zeros((count_beats + 1, width), dtype=np.int64)
    beats = np.zeros((count_beats, width))
    inside = np.zeros((count_beats, width), dtype=np.int64)
    for k in range(count_beats):
        for j in range(width):
            index = peaks[k] + first_offset + j
            if start[k] <= index < end[k]:
                beats[k, j] = y[min(max(index, 0), y.size - 1)]
                inside[k, j] = 1
            sums[k + 1, j] = sums[k, j] + beats[k, j]
            counts[k + 1, j] = counts[k, j] + inside[k, j]
    out = np.zeros((count_beats, width))
    for k in range(count_beats):
        lo = min(max(k - n_beats // 2, 0), count_beats)
        hi = min(max(k + (n_beats - n_beats // 2) + 1, 0), count_beats)
        for j in range(width):
            total = sums[hi, j] - sums[lo, j] - beats[k, j]
            count = counts[hi, j] - counts[lo, j] - inside[k, j]
            if count > 0:
                out[k, j] = total / count
    return out


@jit
def qrs_variant_sums(
    y: NDArray[np.float64],
    aligned: NDArray[np.int64],
    offsets: NDArray[np.int64],
    evaluate: tuple[NDArray[np.int32], NDArray[np.int32], NDArray[np.float64]],
    coefficients: NDArray[np.float64],
    starts: NDArray[np.int64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Every QRS variant's template samples and the five sums of its least-squares fit, per beat.

    ``evaluate`` is the CSR (indptr, indices, data) of the PCHIP evaluation matrix; the template
    samples are ``evaluate @ coefficients`` (points x beats) and the sums (Σt, Σt², Σy, Σty, Σy²;
    variants x beats each) run over each variant's segment of points, the signal read at
    ``offsets + aligned``. Both accumulate in the order of SciPy's CSR product (``csr_matvecs``),
    so the results are the sparse products' to the last bit, without their temporaries.
    """
    indptr, indices, data = evaluate
    points = offsets.size
    beats = aligned.size
    variants = starts.size
    t_qrs = np.zeros((points, beats))
    for p in range(points):
        target = t_qrs[p]
        for jj in range(indptr[p], indptr[p + 1]):
            a = data[jj]
            row = coefficients[indices[jj]]
            for b in range(beats):
                target[b] += a * row[b]
    sums = np.zeros((5, variants, beats))
    for v in range(variants):
        stop = starts[v + 1] if v + 1 < variants else points
        for p in range(starts[v], stop):
            for b in range(beats):
                t = t_qrs[p, b]
                x = y[offsets[p] + aligned[b]]
                sums[0, v, b] += t
                sums[1, v, b] += t * t
                sums[2, v, b] += x
                sums[3, v, b] += t * x
                sums[4, v, b] += x * x
    return t_qrs, sums


@jit
def fitted_artefact(
    template: NDArray[np.float64],
    t_qrs: NDArray[np.float64],
    first_point: NDArray[np.int64],
    width: NDArray[np.int64],
    inside: NDArray[np.bool_],
    scale: NDArray[np.float64],
    offset: NDArray[np.float64],
    half: int,
    outer: int,
) -> tuple[NDArray[np.float64], NDArray[np.int8], NDArray[np.float64]]:
    """Each beat's template with its chosen QRS variant, the section of every cell, the artefact.

    Row b of the grid (offsets −half…half) takes the variant's samples ``t_qrs[first_point[b] + …]``
    where |offset| ≤ width[b]; cells before the QRS are section 0 (P), after it 2 (T), in it 1,
    outside the beat 3; the artefact is ``scale[section]·template + offset[section]`` (sections
    0–2 by position, inside the beat or not).
    """
    beats, columns = template.shape
    points = t_qrs.shape[0]
    values = template.copy()
    section_of = np.empty((beats, columns), dtype=np.int8)
    artefact = np.empty((beats, columns))
    for b in range(beats):
        w = width[b]
        for j in range(-outer, outer + 1):
            if abs(j) <= w:
                values[b, half + j] = t_qrs[min(max(first_point[b] + j + w, 0), points - 1), b]
        for col in range(columns):
            shift = col - half
            section = 0 if shift < -w else (2 if shift > w else 1)
            section_of[b, col] = section if inside[b, col] else 3
            artefact[b, col] = scale[section, b] * values[b, col] + offset[section, b]
    return values, section_of, artefact


@jit
def subtract_templates(
    y: NDArray[np.float64],
    peaks: NDArray[np.int64],
    start: NDArray[np.int64],
    end: NDArray[np.int64],
    template: NDArray[np.float64],
    half: int,
) -> NDArray[np.float64]:
    """``y`` minus each beat's template row (offsets −half…half) placed at its R-peak, within [start, end)."""
    cleaned = y.copy()
    for b in range(peaks.size):
        for i in range(max(start[b], peaks[b] - half), min(end[b], peaks[b] + half + 1)):
            cleaned[i] -= template[b, i - peaks[b] + half]
    return cleaned


@jit
def subtract_sections(
    y: NDArray[np.float64],
    index: NDArray[np.int64],
    section_of: NDArray[np.int8],
    keep: NDArray[np.bool_],
    artefact: NDArray[np.float64],
) -> NDArray[np.float64]:
    """``y`` minus the artefact of the cells whose section (0–2; 3 is outside the beat) is kept.

    ``keep`` is sections x beats; beats do not overlap, so every sample is changed at most once.
    """
    cleaned = y.copy()
    beats, columns = index.shape
    for b in range(beats):
        for j in range(columns):
            section = section_of[b, j]
            if section < 3 and keep[section, b]:
                cleaned[index[b, j]] -= artefact[b, j]
    return cleaned
