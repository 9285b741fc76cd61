"""Compiled loops of the per-beat ECG fit (:mod:`bowden.analysis.emg.ecg_fit`) and of its use.

The fit is chosen beat by beat from running sums over the beat's own samples, without the
beats x offsets grids (index, mask, masked copies, prefix-sum stacks) the NumPy formulation builds;
a fit is then applied (subtracted from a record, added to one, correlated with the bootstrap's EMG) by
recomputing each cell's artefact ``scale·template + offset`` on the fly. Sums run in record order,
where NumPy's reductions sum pairwise: the results equal the NumPy formulation's to rounding
(tests/analysis/test_emg_fit_kernels.py keeps it as the reference, at 1e-12), and the pipeline's
to 1e-9 (tests/analysis/test_emg_pipeline_fixture.py).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from bowden.analysis.emg._kernels import jit


@jit
def best_shifts(
    y: NDArray[np.float64], peaks: NDArray[np.int64], qrs_templates: NDArray[np.float64], max_shift: int
) -> NDArray[np.int64]:
    """Lag −max_shift…max_shift maximising each centred QRS template's product with its beat (first max).

    ``qrs_templates`` is beats x (2·qrs + 1), the template at offsets −qrs…qrs from the R-peak.
    """
    beats, length = qrs_templates.shape
    qrs = (length - 1) // 2
    shifts = np.zeros(beats, dtype=np.int64)
    centred = np.empty(length)
    lags = 2 * max_shift + 1
    scores = np.empty(lags)
    for b in range(beats):
        total = 0.0
        for j in range(length):
            total += qrs_templates[b, j]
        mean = total / length
        for j in range(length):
            centred[j] = qrs_templates[b, j] - mean
        first = peaks[b] - qrs - max_shift
        # All lags side by side (each still summed over j in order): the inner loop vectorises.
        scores[:] = 0.0
        for j in range(length):
            q = centred[j]
            window = y[first + j : first + j + lags]
            for lag in range(lags):
                scores[lag] += q * window[lag]
        best = 0
        for lag in range(1, lags):
            if scores[lag] > scores[best]:
                best = lag
        shifts[b] = best - max_shift
    return shifts


@jit
def qrs_variant_sums(
    y: NDArray[np.float64],
    aligned: NDArray[np.int64],
    offsets: NDArray[np.int64],
    evaluate: tuple[NDArray[np.int32], NDArray[np.int32], NDArray[np.float64]],
    coefficients: NDArray[np.float64],
    starts: NDArray[np.int64],
) -> NDArray[np.float64]:
    """The five sums (Σt, Σt², Σy, Σty, Σy²; variants x beats each) of every QRS variant's LS fit.

    ``evaluate`` is the CSR (indptr, indices, data) of the PCHIP evaluation matrix; the template
    samples are ``evaluate @ coefficients`` (points x beats), the sums run over each variant's
    segment of points, the signal read at ``offsets + aligned``. Both accumulate in the order of
    SciPy's CSR products (``csr_matvecs``), so the sums are the sparse products' to the last bit.
    The samples are made one point at a time (beats side by side, in vector instructions) and not
    kept: :func:`choose_variants` evaluates the chosen variant again.
    """
    indptr, indices, data = evaluate
    beats = aligned.size
    variants = starts.size
    outer = 0
    for p in range(offsets.size):
        outer = max(outer, abs(offsets[p]))
    # The signal around every aligned R-peak, offsets as rows with the beats contiguous.
    window = np.empty((2 * outer + 1, beats))
    for k in range(2 * outer + 1):
        for b in range(beats):
            window[k, b] = y[aligned[b] - outer + k]
    sums = np.zeros((5, variants, beats))
    t = np.empty(beats)
    for v in range(variants):
        s0, s1, s2, s3, s4 = sums[0, v], sums[1, v], sums[2, v], sums[3, v], sums[4, v]
        stop = starts[v + 1] if v + 1 < variants else offsets.size
        for p in range(starts[v], stop):
            jj = indptr[p]
            x_row = window[offsets[p] + outer]
            if indptr[p + 1] - jj == 4:  # a cubic's four coefficients (every point): one pass
                a0, a1, a2, a3 = data[jj], data[jj + 1], data[jj + 2], data[jj + 3]
                r0, r1 = coefficients[indices[jj]], coefficients[indices[jj + 1]]
                r2, r3 = coefficients[indices[jj + 2]], coefficients[indices[jj + 3]]
                for b in range(beats):
                    t[b] = (((0.0 + a0 * r0[b]) + a1 * r1[b]) + a2 * r2[b]) + a3 * r3[b]
            else:
                t[:] = 0.0
                for jj in range(indptr[p], indptr[p + 1]):
                    a = data[jj]
                    row = coefficients[indices[jj]]
                    for b in range(beats):
                        t[b] += a * row[b]
            for b in range(beats):
                x = x_row[b]
                s0[b] += t[b]
                s1[b] += t[b] * t[b]
                s2[b] += x
                s3[b] += t[b] * x
                s4[b] += x * x
    return sums


@jit
def _sign(value: float) -> float:
    """``np.sign`` of a float (NaN stays NaN)."""
    return 1.0 if value > 0.0 else (-1.0 if value < 0.0 else (0.0 if value == 0.0 else value))


@jit
def _pchip_end(m0: float, m1: float) -> float:
    """SciPy's one-sided, shape-preserving end derivative of PCHIP (Moler, pchiptx.m), unit grid."""
    d = (3.0 * m0 - m1) / 2.0
    if _sign(d) != _sign(m0):
        return 0.0
    if _sign(m0) != _sign(m1) and abs(d) > 3.0 * abs(m0):
        return 3.0 * m0
    return d


@jit
def pchip_coefficients(y: NDArray[np.float64]) -> NDArray[np.float64]:
    """PPoly coefficients (4 x intervals x columns) of the PCHIP interpolant of each column of ``y``.

    On the unit grid x = 0, 1, 2, … (at least three points), with the operations of SciPy's
    ``PchipInterpolator`` (Fritsch–Carlson slopes, harmonic-mean derivatives, Moler's end
    derivatives; its divisions by the spacing are by 1, exact), so ``.c`` to the last bit.
    """
    points, columns = y.shape
    m = points - 1
    out = np.empty((4, m, columns))
    slope = np.empty(m)
    derivative = np.empty(points)
    for col in range(columns):
        for i in range(m):
            slope[i] = y[i + 1, col] - y[i, col]
        for i in range(1, m):
            s0, s1 = slope[i - 1], slope[i]
            if _sign(s1) != _sign(s0) or s1 == 0.0 or s0 == 0.0:
                derivative[i] = 0.0
            else:
                derivative[i] = 1.0 / ((3.0 / s0 + 3.0 / s1) / 6.0)  # weights 2h+h = 3 on a unit grid
        derivative[0] = _pchip_end(slope[0], slope[1])
        derivative[m] = _pchip_end(slope[m - 1], slope[m - 2])
        for i in range(m):
            t = derivative[i] + derivative[i + 1] - 2.0 * slope[i]
            out[0, i, col] = t
            out[1, i, col] = slope[i] - derivative[i] - t
            out[2, i, col] = derivative[i]
            out[3, i, col] = y[i, col]
    return out


@jit
def _cell_sums(
    y: NDArray[np.float64],
    row: NDArray[np.float64],
    origin: int,
    start: int,
    end: int,
    first: int,
    stop: int,
    out: NDArray[np.float64],
) -> None:
    """(n, Σt, Σt², Σy, Σty, Σy²) over template columns [first, stop) whose sample lies in [start, end).

    Column ``col`` of ``row`` sits at sample ``origin + col``.
    """
    n = st = stt = sy = sty = syy = 0.0
    for col in range(max(first, start - origin), min(stop, end - origin)):
        t = row[col]
        x = y[origin + col]
        n += 1.0
        st += t
        stt += t * t
        sy += x
        sty += t * x
        syy += x * x
    out[0], out[1], out[2], out[3], out[4], out[5] = n, st, stt, sy, sty, syy


@jit
def _cell_prefix(
    y: NDArray[np.float64],
    row: NDArray[np.float64],
    origin: int,
    start: int,
    end: int,
    first: int,
    out: NDArray[np.float64],
) -> None:
    """Prefix sums (6 x columns + 1, leading 0) of :func:`_cell_sums`' terms from column ``first`` on.

    A column outside [start, end) adds zeros, as the NumPy formulation's masked grids do.
    """
    for k in range(6):
        out[k, 0] = 0.0
    for m in range(out.shape[1] - 1):
        col = first + m
        i = origin + col
        t = row[col] if start <= i < end else 0.0
        x = y[i] if start <= i < end else 0.0
        inside = 1.0 if start <= i < end else 0.0
        out[0, m + 1] = out[0, m] + inside
        out[1, m + 1] = out[1, m] + t
        out[2, m + 1] = out[2, m] + t * t
        out[3, m + 1] = out[3, m] + x
        out[4, m + 1] = out[4, m] + t * x
        out[5, m + 1] = out[5, m] + x * x


@jit
def _section_fit(sums: NDArray[np.float64], section: int, v: int) -> tuple[float, float, float]:
    """``ecg_fit.section_fit`` of one section: LS scale, offset and residual energy from its six sums.

    ``sums[section, v]`` holds (n, Σt, Σt², Σy, Σty, Σy²). A flat or empty template section gets a
    scale of 0 (the offset alone is fitted).
    """
    n, st, stt = sums[section, v, 0], sums[section, v, 1], sums[section, v, 2]
    sy, sty, syy = sums[section, v, 3], sums[section, v, 4], sums[section, v, 5]
    det = n * stt - st * st
    a = (n * sty - st * sy) / det if det > 1e-12 * max(n * stt, 1e-300) else 0.0
    b = (sy - a * st) / max(n, 1.0) if n > 0 else 0.0
    return a, b, max(syy - a * sty - b * sy, 0.0)


@jit
def choose_variants(
    y: NDArray[np.float64],
    aligned: NDArray[np.int64],
    start: NDArray[np.int64],
    end: NDArray[np.int64],
    template: NDArray[np.float64],
    qrs: int,
    stretch: int,
    q_sums: NDArray[np.float64],
    evaluate: tuple[NDArray[np.int32], NDArray[np.int32], NDArray[np.float64]],
    coefficients: NDArray[np.float64],
    first_point: NDArray[np.int64],
) -> tuple[
    NDArray[np.int64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
]:
    """Each beat's QRS variant of least total residual, and its sections' fits.

    ``template`` is beats x (2·half + 1) (offsets −half…half from the aligned R-peak); ``q_sums`` are
    the variants' QRS sums from :func:`qrs_variant_sums` (``evaluate`` and ``coefficients`` as
    there), ``first_point`` the first point of each variant. The P section of the variant of half
    width w is the beat before offset −w, the T section the beat after +w, both summed as a fixed
    part plus the prefix of a band of 2·stretch columns (where the variants differ), as the NumPy
    formulation does.

    Returns the chosen variant (beats), then per section (P, QRS, T) x beats its LS scale, offset,
    residual energy and energy, and each beat's chosen QRS samples at offsets −outer…outer
    (outer = qrs + stretch; valid within ± the chosen width).
    """
    beats, columns = template.shape
    half = (columns - 1) // 2
    outer = qrs + stretch
    variants = 2 * stretch + 1
    indptr, indices, data = evaluate
    points = indptr.size - 1
    best = np.zeros(beats, dtype=np.int64)
    scale = np.zeros((3, beats))
    offset = np.zeros((3, beats))
    sse = np.zeros((3, beats))
    energy = np.zeros((3, beats))
    qrs_values = np.zeros((beats, 2 * outer + 1))
    sums = np.empty((3, variants, 6))
    fixed = np.empty(6)
    band = np.empty((6, 2 * stretch + 1))
    for b in range(beats):
        row = template[b]
        origin = aligned[b] - half
        _cell_sums(y, row, origin, start[b], end[b], 0, half - outer, fixed)
        _cell_prefix(y, row, origin, start[b], end[b], half - outer, band)
        for v in range(variants):
            for k in range(6):
                sums[0, v, k] = fixed[k] + band[k, 2 * stretch - v]
        _cell_sums(y, row, origin, start[b], end[b], half + outer + 1, columns, fixed)
        _cell_prefix(y, row, origin, start[b], end[b], half + qrs - stretch + 1, band)
        for v in range(variants):
            sums[1, v, 0] = 2.0 * (qrs - stretch + v) + 1.0
            for k in range(5):
                sums[1, v, k + 1] = q_sums[k, v, b]
            for k in range(6):
                sums[2, v, k] = fixed[k] + band[k, 2 * stretch] - band[k, v]
        chosen = 0
        least = 0.0
        for v in range(variants):
            total = _section_fit(sums, 0, v)[2] + _section_fit(sums, 1, v)[2] + _section_fit(sums, 2, v)[2]
            if v == 0 or total < least:
                chosen, least = v, total
        best[b] = chosen
        for section in range(3):
            scale[section, b], offset[section, b], sse[section, b] = _section_fit(sums, section, chosen)
            energy[section, b] = sums[section, chosen, 5]
        w = qrs - stretch + chosen
        for j in range(-w, w + 1):
            p = min(max(first_point[chosen] + j + w, 0), points - 1)
            t = 0.0  # row p of evaluate @ coefficients, in qrs_variant_sums' order
            for jj in range(indptr[p], indptr[p + 1]):
                t += data[jj] * coefficients[indices[jj], b]
            qrs_values[b, outer + j] = t
    return best, scale, offset, sse, energy, qrs_values


SUBTRACT, ADD, CORRELATE = 0, 1, 2  # what :func:`apply_fit` does with each sample's artefact


@jit
def apply_fit(
    mode: int,
    e: NDArray[np.float64],
    aligned: NDArray[np.int64],
    start: NDArray[np.int64],
    end: NDArray[np.int64],
    width: NDArray[np.int64],
    template: NDArray[np.float64],
    qrs_values: NDArray[np.float64],
    scale: NDArray[np.float64],
    offset: NDArray[np.float64],
    keep: NDArray[np.bool_],
    out: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Each beat's fitted artefact, sample by sample: ``scale·template + offset`` of its section.

    The section of template column ``col`` of beat b is P (0) before offset −width[b], T (2) after
    +width[b], QRS (1) between, where the chosen variant's samples ``qrs_values`` replace the
    template's. ``mode`` SUBTRACT: ``out`` (a copy of the record) loses the artefact of the
    sections kept (``keep``: 3 x beats); ADD: ``out`` (a copy of the record) gains it; CORRELATE:
    returns Σ artefact·e per section of each beat (3 x beats; zeros otherwise).
    """
    columns = template.shape[1]
    half = (columns - 1) // 2
    outer = (qrs_values.shape[1] - 1) // 2
    products = np.zeros((3, aligned.size))
    for b in range(aligned.size):
        origin = aligned[b] - half
        first = max(start[b], origin) - origin
        stop = min(end[b], origin + columns) - origin
        w = width[b]
        # The beat's columns in three runs (P, QRS, T), each a plain loop over its samples.
        for section in range(3):
            lo = first if section == 0 else max(first, half - w if section == 1 else half + w + 1)
            hi = stop if section == 2 else min(stop, half - w if section == 0 else half + w + 1)
            row = qrs_values[b] if section == 1 else template[b]
            shift = outer - half if section == 1 else 0  # column -> index into row
            a, c = scale[section, b], offset[section, b]
            if mode == SUBTRACT:
                if keep[section, b]:
                    for col in range(lo, hi):
                        out[origin + col] -= a * row[col + shift] + c
            elif mode == ADD:
                for col in range(lo, hi):
                    out[origin + col] += a * row[col + shift] + c
            else:
                total = 0.0
                for col in range(lo, hi):
                    total += (a * row[col + shift] + c) * e[origin + col]
                products[section, b] = total
    return products
