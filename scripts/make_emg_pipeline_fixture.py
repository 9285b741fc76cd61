"""Write tests/fixtures/emg_pipeline.npz: the EMG pipeline's outputs on fixed synthetic inputs.

The fixture pins what the EMG processing computes (the paper's chain with ECG removal, its variants
and the plain steps), so that a faster implementation can be checked against the one before it at
1e-9 (tests/analysis/test_emg_pipeline_fixture.py). Inputs are generated here from fixed seeds, not
stored: :func:`cases` builds them and :func:`outputs` runs every step on them; the test imports both.

Long outputs are stored as a digest to keep the fixture small: every ``DIGEST_STEP``-th sample, plus
the sum of the samples and of their squares over each block of ``DIGEST_STEP`` samples, so a change
of any single sample shows in its block's sums. Short outputs and R-peak indices are stored whole.

Run only to pin a deliberate change of the results: ``python scripts/make_emg_pipeline_fixture.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy import signal as sps

from bowden.analysis import (
    EcgRemovalParameters,
    EmgCheckParameters,
    EmgProcessParameters,
    EmgSignal,
    emg_detect_r_peaks,
    emg_envelope,
    emg_filter,
    emg_pipeline,
    emg_rectify,
    emg_remove_ecg,
)

FIXTURE = Path(__file__).resolve().parents[1] / "tests" / "fixtures" / "emg_pipeline.npz"
DIGEST_STEP = 256
_WHOLE_BELOW = 4096  # arrays with fewer samples are stored whole

# (amplitude, centre s, width s) of the P, Q, R, S, T waves relative to the R-peak (ECGSYN-like).
_WAVES = (
    (0.12, -0.20, 0.025),
    (-0.15, -0.028, 0.008),
    (1.0, 0.0, 0.010),
    (-0.30, 0.028, 0.008),
    (0.30, 0.30, 0.05),
)


def _emg(n: int, rate_hz: float, rng: np.random.Generator, rms_v: float) -> NDArray[np.float64]:
    """Amplitude-modulated band-limited noise (30–300 Hz), ``rms_v`` at full activation."""
    sos = sps.butter(4, [30.0, 300.0], btype="bandpass", fs=rate_hz, output="sos")
    x = sps.sosfilt(sos, rng.standard_normal(n + 2000))[2000:]
    t = np.arange(n) / rate_hz
    activation = 0.55 + 0.45 * np.sin(2.0 * np.pi * t / rng.uniform(1.6, 3.5) + rng.uniform(0.0, 6.0))
    return np.asarray(rms_v * activation * x / x.std(), dtype=np.float64)


def _ecg(n: int, rate_hz: float, rng: np.random.Generator, heart_rate_bpm: float) -> NDArray[np.float64]:
    """ECG with varying RR interval, amplitude and QRS width, 1 mV R wave, V."""
    t = np.arange(n) / rate_hz
    ecg = np.zeros(n)
    r_time = 0.3
    while r_time < t[-1] - 0.1:
        gain = 1e-3 * (1.0 + 0.15 * rng.standard_normal())
        qrs_scale = 1.0 + 0.08 * rng.standard_normal()
        lo, hi = np.searchsorted(t, [r_time - 0.45, r_time + 0.6])
        local = t[lo:hi] - r_time
        for i, (amplitude, centre, width) in enumerate(_WAVES):
            scale = qrs_scale if 1 <= i <= 3 else 1.0
            ecg[lo:hi] += gain * amplitude * np.exp(-0.5 * ((local - centre * scale) / (width * scale)) ** 2)
        r_time += 60.0 / heart_rate_bpm * (1.0 + 0.06 * rng.standard_normal())
    return ecg


def _recording(
    seed: int, duration_s: float, rate_hz: float, ecg_gains: dict[str, float], emg_rms_v: dict[str, float]
) -> EmgSignal:
    rng = np.random.default_rng(seed)
    n = round(duration_s * rate_hz)
    ecg = _ecg(n, rate_hz, rng, heart_rate_bpm=rng.uniform(65.0, 95.0))
    columns = [_emg(n, rate_hz, rng, rms) + ecg_gains.get(name, 0.0) * ecg for name, rms in emg_rms_v.items()]
    return EmgSignal(values=np.column_stack(columns), rate_hz=rate_hz, channels=tuple(emg_rms_v))


def cases() -> dict[str, EmgSignal]:
    """The fixed inputs: a trial-sized recording, a 1 kHz one with an ECG lead, short and tiny ones."""
    trunk = {"pectoralis_major": 1.0, "latissimus_dorsi": -0.35}
    return {
        # 45 s at 2 kHz: ~60 beats (the 40-beat moving template slides), a strong and a weak,
        # inverted ECG, a clean arm muscle, and a trunk muscle whose EMG drowns its ECG.
        "trial": _recording(
            1,
            45.0,
            2000.0,
            trunk | {"deltoid_anterior": 0.8},
            {
                "pectoralis_major": 60e-6,
                "latissimus_dorsi": 150e-6,
                "biceps": 80e-6,
                "deltoid_anterior": 1e-3,
            },
        ),
        # A 1 kHz recording with an ECG lead as the reference channel.
        "lead": _recording(
            2,
            20.0,
            1000.0,
            trunk | {"ecg": 1.0},
            {"pectoralis_major": 100e-6, "latissimus_dorsi": 50e-6, "ecg": 5e-6},
        ),
        # 3 s: a handful of beats (templates of fewer than 40 beats, the bootstrap on all of them).
        "short": _recording(3, 3.0, 2000.0, trunk, {"pectoralis_major": 40e-6, "latissimus_dorsi": 40e-6}),
        # 0.25 s: at most one beat, windows longer than the record.
        "tiny": _recording(4, 0.25, 2000.0, trunk, {"pectoralis_major": 40e-6, "latissimus_dorsi": 40e-6}),
    }


def _results(emg: EmgSignal, name: str) -> dict[str, EmgSignal | NDArray[np.int64]]:
    """Every step to pin on one input, by output name."""
    check = EmgCheckParameters(expected_channels=emg.channels, expected_rate_hz=None)
    variants = {
        "pipeline": EmgProcessParameters(check=check),
        "pipeline_template": EmgProcessParameters(check=check, ecg_removal="template"),
        "pipeline_none": EmgProcessParameters(check=check, ecg_removal="none"),
    }
    if name == "lead":
        variants["pipeline_reference"] = EmgProcessParameters(check=check, ecg_reference_channel="ecg")
    if name == "trial":
        described = EcgRemovalParameters(gate=False, denoise_template=False)
        variants["pipeline_described"] = EmgProcessParameters(check=check, ecg=described)
        variants["pipeline_odd_window"] = EmgProcessParameters(check=check, envelope_window_s=0.0105)
    results: dict[str, EmgSignal | NDArray[np.int64]] = {}
    for label, params in variants.items():
        out = emg_pipeline(emg, params)
        results[f"{label}/clean"] = out.clean
        results[f"{label}/envelope"] = out.envelope
        for channel, peaks in out.info.r_peaks.items():
            results[f"{label}/r_peaks/{channel}"] = peaks
    filtered = emg_filter(emg)
    results["filter"] = filtered
    results["rectify"] = emg_rectify(filtered)
    results["envelope"] = emg_envelope(emg_rectify(filtered))
    results["envelope_1s"] = emg_envelope(filtered, window_s=1.0)
    results["filter_10_450_order4"] = emg_filter(emg, low_hz=10.0, high_hz=450.0, order=4)
    for channel in ("pectoralis_major", "latissimus_dorsi", "deltoid_anterior"):
        if channel in emg.channels:
            results[f"r_peaks/{channel}"] = emg_detect_r_peaks(emg, channel=channel)
            unchecked = emg_detect_r_peaks(emg, channel=channel, min_rr_fraction=0.0)
            results[f"r_peaks_unchecked/{channel}"] = unchecked
    peaks = emg_detect_r_peaks(emg, channel="pectoralis_major")
    removals = {
        "remove_ecg_adaptive": EcgRemovalParameters(),
        "remove_ecg_no_stretch": EcgRemovalParameters(stretch_samples=0, max_shift_samples=3),
        "remove_ecg_template": EcgRemovalParameters(method="template", template_beats=7),
    }
    for label, removal in removals.items():
        results[label] = emg_remove_ecg(filtered, peaks, parameters=removal)
    return results


def digest(values: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
    """Whole array when short; else every DIGEST_STEP-th sample and per-block sums of x and x².

    ``scale`` (the largest magnitude) sets the test's absolute tolerance: a block sum moves by as
    much as any one of its samples does, so it is compared at the samples' tolerance.
    """
    scale = np.array(float(np.max(np.abs(values), initial=0.0)))
    if values.shape[0] < _WHOLE_BELOW:
        return {"whole": values, "scale": scale}
    blocks = values.shape[0] // DIGEST_STEP
    shaped = values[: blocks * DIGEST_STEP].reshape(blocks, DIGEST_STEP, *values.shape[1:])
    return {
        "every": values[::DIGEST_STEP],
        "sum": shaped.sum(axis=1),
        "sum_sq": (shaped * shaped).sum(axis=1),
        "tail": values[blocks * DIGEST_STEP :],
        "scale": scale,
    }


def outputs() -> dict[str, NDArray[np.float64] | NDArray[np.int64]]:
    """Every pinned array, keyed ``<case>/<step>/<part>`` (inputs' digests under ``<case>/input``)."""
    arrays: dict[str, NDArray[np.float64] | NDArray[np.int64]] = {}
    for name, emg in cases().items():
        for part, array in digest(emg.values).items():
            arrays[f"{name}/input/{part}"] = array
        arrays[f"{name}/input/rate_hz"] = np.array(emg.rate_hz)
        for label, result in _results(emg, name).items():
            if isinstance(result, EmgSignal):
                for part, array in digest(np.asarray(result.values)).items():
                    arrays[f"{name}/{label}/{part}"] = array
            else:
                arrays[f"{name}/{label}/peaks"] = np.asarray(result, dtype=np.int64)
    return arrays


def main() -> None:
    arrays = outputs()
    np.savez_compressed(FIXTURE, **arrays)  # type: ignore[arg-type]
    print(f"{FIXTURE}: {len(arrays)} arrays, {FIXTURE.stat().st_size / 1e3:.0f} kB", file=sys.stderr)


if __name__ == "__main__":
    main()
