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

Target (issue 6): ≤ 15 s for the whole study here. Prints the times and their ratios; no assertion.

Usage: ``python benchmarks/analysis.py [--participants 17] [--seed 0] [--workers 2]``
"""

from __future__ import annotations

import argparse
import functools
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from numpy.typing import NDArray
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
    from pyemgpipeline.processors import BandpassFilter, FullWaveRectifier, LinearEnvelope

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
    parallel = f"bowden paper pipeline, {args.workers} workers"
    timings = {
        "bowden paper pipeline": 0.0,
        parallel: 0.0,
        "bowden same steps (no ECG)": 0.0,
        "pyemgpipeline": 0.0,
    }
    # CPU time of this process as well as wall time: on a shared machine the wall clock also counts
    # the time other processes hold the cores, the CPU time does not.
    cpu = dict.fromkeys(timings, 0.0)
    n_trials = args.participants * len(CONDITIONS) * len(SPEEDS)
    # All trials in memory (≈ 1.8 GB for 17 participants), so every method sees the same list and
    # the workers are never idle waiting for the next batch to be generated.
    trials = [synthetic_trial(rng, rng.uniform(50.0, 90.0)) for _ in range(n_trials)]
    samples = sum(emg.values.size for emg in trials)
    spawn = multiprocessing.get_context("spawn")  # as analyse_study starts its workers
    with ProcessPoolExecutor(max_workers=args.workers, mp_context=spawn) as pool:
        one_trial = functools.partial(bowden_steps, params=params)
        warm_up = [synthetic_trial(np.random.default_rng(), 1.0) for _ in range(args.workers)]
        list(pool.map(one_trial, warm_up))  # start the workers before the clock runs
        runs = (
            ("bowden paper pipeline", lambda: [bowden_steps(e, params) for e in trials]),
            (parallel, lambda: list(pool.map(one_trial, trials))),
            ("bowden same steps (no ECG)", lambda: [bowden_same_steps(e) for e in trials]),
            ("pyemgpipeline", lambda: [pyemgpipeline_steps(e) for e in trials]),
        )
        for name, run in runs:
            start, start_cpu = time.perf_counter(), time.process_time()
            run()
            timings[name] += time.perf_counter() - start
            cpu[name] += time.process_time() - start_cpu
    print(
        f"study: {args.participants} participants, {n_trials} trials, 8 muscles, "
        f"{samples / 1e6:.0f} M samples"
    )
    print(f"  {'':38s} {'wall':>9s} {'CPU':>9s}")
    for name, seconds in timings.items():
        print(f"  {name:38s} {seconds:7.2f} s {cpu[name]:7.2f} s")
    serial, ours = timings["bowden paper pipeline"], timings[parallel]
    for name, seconds in (("serial", serial), (f"{args.workers} workers", ours)):
        print(
            f"target {TARGET_S:.0f} s, {name}: {'met' if seconds <= TARGET_S else 'NOT met'} "
            f"({seconds / TARGET_S:.2f} of the budget)"
        )
    print(
        f"CPU time of the paper pipeline: {cpu['bowden paper pipeline']:.2f} s "
        f"({'within' if cpu['bowden paper pipeline'] <= TARGET_S else 'over'} the budget)"
    )
    print(f"speed-up with {args.workers} workers: {serial / ours:.2f}")
    reference = timings["pyemgpipeline"]
    print(f"ratio bowden paper pipeline ({args.workers} workers) / pyemgpipeline: {ours / reference:.2f}")
    print(f"ratio bowden paper pipeline (serial) / pyemgpipeline:    {serial / reference:.2f}")
    print(
        f"ratio bowden same steps / pyemgpipeline:               "
        f"{timings['bowden same steps (no ECG)'] / reference:.2f}"
    )


if __name__ == "__main__":
    main()
