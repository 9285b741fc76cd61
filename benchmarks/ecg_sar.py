"""Signal-to-artefact ratio of the ECG removal methods on two kinds of synthetic contaminated EMG.

SAR = 10·log10(Σ emg² / Σ (output − emg)²) with emg the clean EMG after the same 20–400 Hz
band-pass (tests/analysis/test_emg_ecg.py): ECG left in and EMG taken out both count. R-peaks are
detected on the contaminated channel, as ``emg_process`` does. Sources:

- ``test``: the EMG and ECG of tests/analysis/conftest.py (30–300 Hz 4th-order noise, an ECG with
  beat-to-beat changes of rate, amplitude and QRS width, 1 mV R wave);
- ``sim``: the generators of :mod:`bowden.sim.emg` (30–250 Hz 2nd-order carrier with more power
  below 30 Hz, 3 µV amplifier noise, the simulation's ECG at 72 bpm, 1 mV R wave).

Both with a smooth activation between 0.1 and 1, 40 s, EMG RMS 30/100/300/1000 µV, seeds 0–2.
Prints mean ± half range (dB) per method. "pure EMG" is the default method run on the EMG alone at
the true R-peaks: what it takes from EMG without any ECG.

Usage: ``python benchmarks/ecg_sar.py [--seeds 3] [--source test sim]``
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy import signal as sps

from bowden.analysis import EcgRemovalParameters, EmgSignal, emg_detect_r_peaks, emg_filter, emg_remove_ecg
from bowden.sim.emg import BASELINE_NOISE_V, ecg_artefact, emg_carrier

# The test suite's generators, loaded from their file (tests/ is not a package on sys.path).
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "analysis"))
from conftest import RATE_HZ, ecg_wave, emg_noise, smooth_activation

LEVELS_V = (30e-6, 100e-6, 300e-6, 1000e-6)
Case = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]  # emg, ecg, true peaks


def test_case(seed: int, emg_rms_v: float, duration_s: float) -> Case:
    rng = np.random.default_rng(seed)
    n = int(duration_s * RATE_HZ)
    emg = emg_rms_v * smooth_activation(n, rng) * emg_noise(n, rng)
    ecg, peaks = ecg_wave(n, rng)
    return emg, ecg, peaks


def sim_case(seed: int, emg_rms_v: float, duration_s: float) -> Case:
    rng = np.random.default_rng(1000 + seed)
    n = int(duration_s * RATE_HZ)
    time_s = np.arange(n) / RATE_HZ
    emg = emg_rms_v * smooth_activation(n, rng) * emg_carrier(n, RATE_HZ, rng)
    emg += BASELINE_NOISE_V * rng.standard_normal(n)
    ecg = ecg_artefact(time_s, 72.0, 1.0, rng)
    peaks, _ = sps.find_peaks(ecg, height=0.5e-3, distance=int(0.3 * RATE_HZ))
    return emg, ecg, peaks.astype(np.int64)


def sar_db(output: NDArray[np.float64], truth: NDArray[np.float64]) -> float:
    return float(10.0 * np.log10(np.sum(truth**2) / np.sum((output - truth) ** 2)))


def methods() -> dict[str, Callable[[EmgSignal, NDArray[np.int64]], NDArray[np.float64]]]:
    def removal(**options: object) -> Callable[[EmgSignal, NDArray[np.int64]], NDArray[np.float64]]:
        parameters = EcgRemovalParameters(**options)  # type: ignore[arg-type]
        return lambda band, peaks: np.asarray(emg_remove_ecg(band, peaks, parameters=parameters).values[:, 0])

    high_pass = sps.butter(4, 30.0, "highpass", fs=RATE_HZ, output="sos")
    return {
        "before": lambda band, peaks: np.asarray(band.values[:, 0]),
        "adaptive": removal(),
        "as described": removal(gate=False, denoise_template=False),
        "plain": removal(method="template"),
        "30 Hz high-pass": lambda band, peaks: sps.sosfiltfilt(high_pass, band.values[:, 0]),
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--source", nargs="+", default=["test", "sim"], choices=["test", "sim"])
    parser.add_argument("--duration", type=float, default=40.0)
    args = parser.parse_args(argv)
    table = methods()
    for source in args.source:
        make = test_case if source == "test" else sim_case
        print(f"source: {source}")
        print("  " + f"{'EMG RMS':>8s}" + "".join(f"{name:>17s}" for name in [*table, "pure EMG"]))
        for level in LEVELS_V:
            results: dict[str, list[float]] = {name: [] for name in [*table, "pure EMG"]}
            for seed in range(args.seeds):
                emg, ecg, true_peaks = make(seed, level, args.duration)
                raw = EmgSignal(values=emg + ecg, rate_hz=RATE_HZ)
                truth = emg_filter(EmgSignal(values=emg, rate_hz=RATE_HZ)).values[:, 0]
                peaks = emg_detect_r_peaks(raw)
                band = emg_filter(raw)
                for name, run in table.items():
                    results[name].append(sar_db(run(band, peaks), truth))
                clean = emg_filter(EmgSignal(values=emg, rate_hz=RATE_HZ))
                out = emg_remove_ecg(clean, true_peaks).values[:, 0]
                results["pure EMG"].append(sar_db(out, truth))
            cells = "".join(
                f"{np.mean(v):9.1f} ± {(np.max(v) - np.min(v)) / 2:4.1f}" for v in results.values()
            )
            print(f"  {level * 1e6:5.0f} µV{cells}")


if __name__ == "__main__":
    main()
