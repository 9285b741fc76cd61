"""The compiled ECG fit (ecg_fit + _fit_kernels) equals its plain NumPy/SciPy formulation.

The reference below is the fit as it was written before it was compiled: beats x offsets grids
(index, mask, masked copies), prefix sums along the grid, SciPy's sparse products for the QRS
variants, least squares per section and variant, ``argmin`` over the variants, and the artefact as a
grid. Random signals and templates (no ties between variants or lags), compared at 1e-12; the QRS
sums, which accumulate in the sparse products' order, exactly.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray
from scipy.interpolate import PchipInterpolator

from bowden.analysis.emg._fit_kernels import qrs_variant_sums
from bowden.analysis.emg.ecg import _beat_bounds
from bowden.analysis.emg.ecg_fit import _qrs_variant_grid, alignment_shifts, fit_beats, pchip_coefficients

_TOLERANCE = 1e-12


def _section_fit(sums: tuple[NDArray[np.float64], ...]) -> tuple[NDArray[np.float64], ...]:
    n, st, stt, sy, sty, syy = sums
    det = n * stt - st * st
    ok = det > 1e-12 * np.maximum(n * stt, 1e-300)
    a = np.where(ok, (n * sty - st * sy) / np.where(ok, det, 1.0), 0.0)
    b = np.where(n > 0, (sy - a * st) / np.maximum(n, 1.0), 0.0)
    return a, b, np.maximum(syy - a * sty - b * sy, 0.0)


def _prefix(band: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.concatenate([np.zeros((*band.shape[:-1], 1)), np.cumsum(band, axis=-1)], axis=-1)


def _reference_shifts(
    y: NDArray[np.float64],
    peaks: NDArray[np.int64],
    template: NDArray[np.float64],
    half: int,
    qrs: int,
    shift: int,
) -> NDArray[np.int64]:
    q = template[:, half - qrs : half + qrs + 1]
    q = q - q.mean(axis=1, keepdims=True)
    span = np.arange(-qrs - shift, qrs + shift + 1)
    windows = sliding_window_view(y[peaks[:, np.newaxis] + span], 2 * qrs + 1, axis=1)
    return np.argmax(np.einsum("bj,blj->bl", q, windows), axis=1) - shift


def _reference_fit(
    y: NDArray[np.float64],
    aligned: NDArray[np.int64],
    start: NDArray[np.int64],
    end: NDArray[np.int64],
    template: NDArray[np.float64],
    half: int,
    qrs: int,
    stretch: int,
) -> dict[str, NDArray[np.float64]]:
    """The fit on beats x offsets grids; the artefact and each cell's section (3: outside) as grids."""
    n_beats = aligned.size
    offsets = np.arange(-half, half + 1)
    index = np.clip(aligned[:, np.newaxis] + offsets, 0, y.size - 1)
    inside = (offsets >= (start - aligned)[:, np.newaxis]) & (offsets < (end - aligned)[:, np.newaxis])
    widths = qrs + np.arange(-stretch, stretch + 1)
    yz = np.where(inside, y[index], 0.0)
    tz = np.where(inside, template, 0.0)
    outer = qrs + stretch

    def terms(columns: slice) -> NDArray[np.float64]:
        t, x = tz[:, columns], yz[:, columns]
        return np.stack([inside[:, columns].astype(np.float64), t, t * t, x, t * x, x * x])

    p_fixed = terms(slice(0, half - outer)).sum(axis=-1)
    t_fixed = terms(slice(half + outer + 1, offsets.size)).sum(axis=-1)
    p_band = _prefix(terms(slice(half - outer, half - qrs + stretch)))
    t_band = _prefix(terms(slice(half + qrs - stretch + 1, half + outer + 1)))
    d = widths - qrs
    p_sums = tuple(p_fixed[:, :, np.newaxis] + p_band[:, :, stretch - d])
    t_sums = tuple(t_fixed[:, :, np.newaxis] + t_band[:, :, -1:] - t_band[:, :, d + stretch])
    grid = _qrs_variant_grid(qrs, stretch)
    coefficients = pchip_coefficients(template[:, half - qrs : half + qrs + 1].T).reshape(
        4 * 2 * qrs, n_beats
    )
    t_qrs = grid.evaluate @ coefficients  # points x beats
    x_qrs = y[grid.offsets[:, np.newaxis] + aligned]
    sums = [grid.segment_sum @ v for v in (t_qrs, t_qrs * t_qrs, x_qrs, t_qrs * x_qrs, x_qrs * x_qrs)]
    q_sums = (np.broadcast_to(2.0 * widths + 1.0, (n_beats, widths.size)), *(s.T for s in sums))
    fits = [_section_fit(s) for s in (p_sums, q_sums, t_sums)]
    best = np.argmin(fits[0][2] + fits[1][2] + fits[2][2], axis=1)
    rows = np.arange(n_beats)
    width = widths[best]
    values = template.copy()
    for b in range(n_beats):
        w = width[b]
        values[b, half - w : half + w + 1] = t_qrs[grid.starts[best[b]] : grid.starts[best[b]] + 2 * w + 1, b]
    section = np.where(offsets < -width[:, np.newaxis], 0, np.where(offsets > width[:, np.newaxis], 2, 1))
    scale = np.stack([f[0][rows, best] for f in fits])
    offset = np.stack([f[1][rows, best] for f in fits])
    return {
        "width": width,
        "scale": scale,
        "offset": offset,
        "sse": np.stack([f[2][rows, best] for f in fits]),
        "energy": np.stack([s[5][rows, best] for s in (p_sums, q_sums, t_sums)]),
        "index": index,
        "inside": inside,
        "section": np.where(inside, section, 3),
        "artefact": scale[section, rows[:, np.newaxis]] * values + offset[section, rows[:, np.newaxis]],
        "t_qrs": t_qrs,
        "q_sums": np.stack(sums),
    }


def _case(seed: int, qrs: int, stretch: int, shift: int) -> dict[str, object]:
    """A random record with beats 0.3–0.45 s apart, random templates, their R-peaks aligned."""
    rng = np.random.default_rng(seed)
    peaks = np.cumsum(rng.integers(600, 900, size=30)).astype(np.int64)
    n = int(peaks[-1] + 700)
    y = rng.standard_normal(n)
    start, end = _beat_bounds(peaks, n, 2000)
    half = int(max(np.max(peaks - start), np.max(end - 1 - peaks))) + shift
    template = rng.standard_normal((peaks.size, 2 * half + 1))
    return {"y": y, "peaks": peaks, "start": start, "end": end, "template": template, "half": half}


@pytest.mark.parametrize(("seed", "qrs", "stretch", "shift"), [(0, 110, 10, 10), (1, 20, 4, 3), (2, 7, 0, 0)])
def test_fit_equals_the_numpy_formulation(seed: int, qrs: int, stretch: int, shift: int) -> None:
    case = _case(seed, qrs, stretch, shift)
    y, peaks, start, end = case["y"], case["peaks"], case["start"], case["end"]
    template, half = case["template"], case["half"]
    assert isinstance(y, np.ndarray) and isinstance(peaks, np.ndarray) and isinstance(template, np.ndarray)
    assert isinstance(start, np.ndarray) and isinstance(end, np.ndarray) and isinstance(half, int)
    shifts = alignment_shifts(y, peaks, template, half, qrs, shift)
    if shift:
        np.testing.assert_array_equal(shifts, _reference_shifts(y, peaks, template, half, qrs, shift))
    aligned = peaks + shifts
    fit = fit_beats(y, aligned, start, end, template, half, qrs, stretch)
    want = _reference_fit(y, aligned, start, end, template, half, qrs, stretch)
    np.testing.assert_array_equal(fit.width, want["width"])
    for key in ("scale", "offset", "sse", "energy"):
        got, expected = getattr(fit, key), want[key]
        np.testing.assert_allclose(got, expected, rtol=_TOLERANCE, atol=_TOLERANCE * np.abs(expected).max())

    # Applied: subtracted (some sections kept), added to a record, correlated with a record.
    rng = np.random.default_rng(seed + 100)
    keep = rng.random((3, peaks.size)) < 0.6
    index, inside, section, artefact = want["index"], want["inside"], want["section"], want["artefact"]
    assert isinstance(inside, np.ndarray) and isinstance(section, np.ndarray)
    subtracted = y.copy()
    kept = inside & np.take_along_axis(keep.T, np.minimum(section, 2), axis=1)
    subtracted[index[kept]] -= artefact[kept]
    np.testing.assert_allclose(fit.subtracted_from(y, keep), subtracted, rtol=_TOLERANCE, atol=_TOLERANCE)
    e = rng.standard_normal(y.size)
    placed = np.zeros(y.size)
    placed[index[inside]] = artefact[inside]
    np.testing.assert_allclose(fit.added_to(e), placed + e, rtol=_TOLERANCE, atol=_TOLERANCE)
    products = np.where(inside, artefact * e[index], 0.0)
    expected = np.stack([np.sum(np.where(section == s, products, 0.0), axis=1) for s in range(3)])
    scale = np.abs(products).sum(axis=1).max()
    np.testing.assert_allclose(fit.products(e), expected, rtol=_TOLERANCE, atol=_TOLERANCE * scale)


def test_qrs_variant_sums_are_the_sparse_products_to_the_last_bit() -> None:
    case = _case(3, 25, 5, 0)
    y, peaks, template, half = case["y"], case["peaks"], case["template"], case["half"]
    assert isinstance(y, np.ndarray) and isinstance(peaks, np.ndarray) and isinstance(template, np.ndarray)
    assert isinstance(half, int)
    grid = _qrs_variant_grid(25, 5)
    coefficients = pchip_coefficients(template[:, half - 25 : half + 26].T).reshape(4 * 50, peaks.size)
    evaluate = (grid.evaluate.indptr, grid.evaluate.indices, grid.evaluate.data)
    got = qrs_variant_sums(y, peaks, grid.offsets, evaluate, coefficients, grid.starts)
    t = grid.evaluate @ coefficients
    x = y[grid.offsets[:, np.newaxis] + peaks]
    want = np.stack([grid.segment_sum @ v for v in (t, t * t, x, t * x, x * x)])
    np.testing.assert_array_equal(got, want)


def test_pchip_coefficients_are_scipys_to_the_last_bit() -> None:
    rng = np.random.default_rng(4)
    y = rng.standard_normal((41, 30)).cumsum(axis=0)
    y[10:14, 3] = 1.5  # flat runs, sign changes and repeated values exercise every branch
    y[:, 4] = np.round(y[:, 4])
    y[:3, 5] = [0.0, 1.0, 0.0]
    want = PchipInterpolator(np.arange(y.shape[0]), y, axis=0).c
    np.testing.assert_array_equal(pchip_coefficients(y), want)
    np.testing.assert_array_equal(pchip_coefficients(np.ascontiguousarray(y[:, ::-1].T).T), want[:, :, ::-1])
