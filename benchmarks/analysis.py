"""Benchmark: EMG processing of a whole simulated study, and the same steps in pyemgpipeline.

A study of the paper's size: 17 participants x 12 trials (4 conditions x 3 speeds) x 8 muscles at
2 kHz, each trial 50–90 s long. Synthetic EMG (amplitude-modulated band-limited noise) with a
synthetic ECG on pectoralis major and latissimus dorsi is generated per trial (not timed); the
timed part is bowden's paper pipeline (channel checks, R-peaks, 20–400 Hz zero-phase band-pass,
adaptive ECG template subtraction, rectification, 100 ms RMS envelope) and, in the same run,
pyemgpipeline's closest chain (its zero-phase Butterworth band-pass of effective order 6 = order 3
forward-backward, full-wave rectifier, linear envelope; it has no ECG removal and no RMS window).

The paper pipeline is timed twice: one trial after another, and ``--workers`` trials at a time in
worker processes, as ``analyse_study(..., workers=)`` (and so ``bowden study``/``bowden analyze``) runs
it (threads measured no faster than one: the many mid-sized NumPy steps hold the GIL). The pool is
started before the clock runs; pickling the trials to the workers is timed.
All trials are generated first (not timed) and kept in memory, about 1.8 GB.

Targets: ≤ 15 s for the whole study here (issue 6); the paper pipeline (ECG removal included) no
slower than pyemgpipeline's chain (ratio ≤ 1.0) and the same steps ≥ 3× faster (ratio ≤ 0.33)
(issue 19). Every method is warmed up on a short trial first (imports, compiled kernels' caches),
then the serial methods run trial by trial in turn, so that the machine's load weighs on all alike.

Two clocks, both printed: *wall* is ``time.perf_counter`` (what a user waits; on a shared machine
it also counts the time other processes hold the cores) and *CPU* is ``time.process_time`` of this
process (the work itself; the workers' CPU time is not in it, so the parallel run has wall time
only). The issue-19 ratios are judged on CPU time and printed on both clocks. No assertion.

Usage: ``python benchmarks/analysis.py [--participants 17] [--seed 0] [--workers 2]``
(``--workers 0`` skips the parallel run).
"""

from __future__ import annotations

import argparse
import functools
import multiprocessing
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from numpy.typing import NDArray
from pyemgpipeline.processors import (  # type: ignore[import-untyped]
    BandpassFilter,
    FullWaveRectifier,
    LinearEnvelope,
)
from scipy import signal as sps

from bowden.analysis import (
    EmgProcessParameters,
    EmgSignal,
    emg_envelope,
    emg_filter,
    emg_pipeline,
    emg_rectify,
)
from bowden.contracts import CONDITIONS, EMG_RATE_HZ, MUSCLES, SPEEDS

TARGET_S = 15.0
TARGET_PIPELINE_RATIO = 1.0  # paper pipeline / pyemgpipeline (issue 19)
TARGET_SAME_STEPS_RATIO = 0.33  # bowden same steps / pyemgpipeline (issue 19)


def synthetic_trial(rng: np.random.Generator, duration_s: float) -> EmgSignal:
    """Eight muscles of amplitude-modulated 20–450 Hz noise; ECG added to the two trunk muscles."""
    n = int(duration_s * EMG_RATE_HZ)
    t = np.arange(n) / EMG_RATE_HZ
    sos = sps.butter(2, [20.0, 450.0], btype="bandpass", fs=EMG_RATE_HZ, output="sos")
    noise = sps.sosfilt(sos, rng.standard_normal((n, len(MUSCLES))), axis=0)
    period = rng.uniform(1.6, 5.0)
    activation = 0.3 + np.sin(np.pi * np.mod(t, period) / period) ** 2
    emg = 40e-6 * activation[:, None] * noise / noise.std(axis=0)
    ecg = _ecg(n, rng)
    for name in ("pectoralis_major", "latissimus_dorsi"):
        emg[:, MUSCLES.index(name)] += ecg * rng.uniform(0.3, 1.0)
    return EmgSignal(values=emg, rate_hz=EMG_RATE_HZ, channels=MUSCLES)


def _ecg(n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    offsets = np.arange(-0.3, 0.45, 1.0 / EMG_RATE_HZ)
    beat = 1e-3 * (
        np.exp(-0.5 * (offsets / 0.01) ** 2)
        - 0.25 * np.exp(-0.5 * ((offsets - 0.028) / 0.008) ** 2)
        + 0.3 * np.exp(-0.5 * ((offsets - 0.3) / 0.05) ** 2)
    )
    ecg = np.zeros(n + beat.size)
    position = 0.4
    while position * EMG_RATE_HZ < n:
        start = int(position * EMG_RATE_HZ)
        ecg[start : start + beat.size] += beat * (1.0 + 0.1 * rng.standard_normal())
        position += 0.8 * (1.0 + 0.05 * rng.standard_normal())
    return ecg[:n]


def bowden_steps(emg: EmgSignal, params: EmgProcessParameters) -> NDArray[np.float64]:
    return np.asarray(emg_pipeline(emg, params).envelope.values)


def bowden_same_steps(emg: EmgSignal) -> NDArray[np.float64]:
    return np.asarray(emg_envelope(emg_rectify(emg_filter(emg))).values)


def pyemgpipeline_steps(emg: EmgSignal) -> NDArray[np.float64]:
    x = BandpassFilter(emg.rate_hz, bf_order=6, bf_cutoff_fq_lo=20, bf_cutoff_fq_hi=400).apply(emg.values)
    x = FullWaveRectifier().apply(x)
    return np.asarray(LinearEnvelope(emg.rate_hz, le_order=4, le_cutoff_fq=6).apply(x))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--participants", type=int, default=17)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    params = EmgProcessParameters()
    n_trials = args.participants * len(CONDITIONS) * len(SPEEDS)
    # All trials in memory (≈ 1.8 GB for 17 participants), so every method sees the same list and
    # the workers are never idle waiting for the next batch to be generated.
    trials = [synthetic_trial(rng, rng.uniform(50.0, 90.0)) for _ in range(n_trials)]
    samples = sum(emg.values.size for emg in trials)
    serial: dict[str, Callable[[EmgSignal], NDArray[np.float64]]] = {
        "bowden paper pipeline": functools.partial(bowden_steps, params=params),
        "bowden same steps (no ECG)": bowden_same_steps,
        "pyemgpipeline": pyemgpipeline_steps,
    }
    warm_up = synthetic_trial(np.random.default_rng(), 2.0)
    for method in serial.values():
        method(warm_up)  # imports, filter designs, compiled kernels: not part of the timed work
    wall = dict.fromkeys(serial, 0.0)
    cpu = dict.fromkeys(serial, 0.0)
    # Trial by trial, every method in turn: a change of the machine's load during the run then
    # weighs on all methods alike instead of on whichever ran at the time.
    for emg in trials:
        for name, method in serial.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            method(emg)
            wall[name] += time.perf_counter() - start
            cpu[name] += time.process_time() - start_cpu
    parallel = f"bowden paper pipeline, {args.workers} workers"
    if args.workers > 0:
        spawn = multiprocessing.get_context("spawn")  # as analyse_study starts its workers
        with ProcessPoolExecutor(max_workers=args.workers, mp_context=spawn) as pool:
            one_trial = serial["bowden paper pipeline"]
            list(pool.map(one_trial, [warm_up] * args.workers))  # start the workers before the clock
            start = time.perf_counter()
            list(pool.map(one_trial, trials))
            wall[parallel] = time.perf_counter() - start
    print(
        f"study: {args.participants} participants, {n_trials} trials, 8 muscles, "
        f"{samples / 1e6:.0f} M samples"
    )
    print(f"  {'':38s} {'wall':>9s} {'CPU':>9s}")
    for name, seconds in wall.items():
        cpu_text = f"{cpu[name]:7.2f} s" if name in cpu else f"{'-':>9s}"
        print(f"  {name:38s} {seconds:7.2f} s {cpu_text}")
    ours = cpu["bowden paper pipeline"]
    print(
        f"issue 6 target {TARGET_S:.0f} s, CPU time of the paper pipeline: {ours:.2f} s "
        f"({'met' if ours <= TARGET_S else 'NOT met'}, {ours / TARGET_S:.2f} of the budget)"
    )
    if parallel in wall:
        print(
            f"  wall with {args.workers} workers: {wall[parallel]:.2f} s "
            f"(speed-up {wall['bowden paper pipeline'] / wall[parallel]:.2f} over serial)"
        )
    print("issue 19 ratios to pyemgpipeline's chain (target on CPU time):   CPU    wall  target")
    for name, target in (
        ("bowden paper pipeline", TARGET_PIPELINE_RATIO),
        ("bowden same steps (no ECG)", TARGET_SAME_STEPS_RATIO),
    ):
        ratio_cpu, ratio_wall = cpu[name] / cpu["pyemgpipeline"], wall[name] / wall["pyemgpipeline"]
        verdict = "met" if ratio_cpu <= target else "NOT met"
        label = f"{name} / pyemgpipeline"
        print(f"  {label:62s} {ratio_cpu:5.2f}  {ratio_wall:5.2f}  ≤ {target:.2f} {verdict}")


if __name__ == "__main__":
    main()
