"""Time each stage of the default `bowden study` (17 participants, the paper's protocol).

Run: python benchmarks/study.py [--participants N] [--workers N] [--keep DIR] [--profile FILE]
                               [--muscles simple|musculoskeletal|both]
Prints wall and CPU seconds per stage (the CPU of the worker processes included) and CPU/wall, the
number of cores a stage kept busy; then the total against the issue's target (≤ 30 s warm on 2 cores,
≤ 60 s for a first run in a fresh venv, compilation included) and the load of the machine (on a
shared machine the wall clock also counts other processes' time; the CPU time does not).
``--profile FILE`` writes a cProfile of this (the parent) process; workers are not profiled.
``--muscles both`` runs the study once with each muscle model, one after the other in this process
(each warm: run once before to fill the caches), and prints the musculoskeletal one's wall and CPU
time as a ratio to the simple one's, which a loaded machine distorts less than either time alone.
"""

from __future__ import annotations

import argparse
import cProfile
import os
import tempfile
import time
from pathlib import Path
from typing import Literal

from bowden.study.pipeline import StudySettings, run_study
from bowden.study.stage_clock import process_tree_cpu

WARM_TARGET_S = 30.0
COLD_TARGET_S = 60.0
DOCUMENTED_SIMPLE_S = 26.9  # the default study warm on the idle 2-core machine (docs/study.md: 26.6-27.2 s)


def run_once(args: argparse.Namespace, muscles: Literal["simple", "musculoskeletal"]) -> tuple[float, float]:
    """One study with ``muscles``; prints its stages; returns its wall and CPU seconds."""
    settings = StudySettings(participants=args.participants, muscles=muscles)
    load_before = os.getloadavg()
    profiler = cProfile.Profile() if args.profile else None
    with tempfile.TemporaryDirectory() as tmp:
        out = args.keep / muscles if args.keep is not None else Path(tmp)
        start, start_cpu = time.perf_counter(), process_tree_cpu()
        if profiler is not None:
            profiler.enable()
        result = run_study(settings, out, force=True, workers=args.workers)
        if profiler is not None:
            profiler.disable()
        total, total_cpu = time.perf_counter() - start, process_tree_cpu() - start_cpu
        size_mb = result.store.stat().st_size / 1e6
    if profiler is not None:
        profiler.dump_stats(args.profile.with_suffix(f".{muscles}{args.profile.suffix}"))
    print(f"--muscles {muscles}: {args.participants} participants, {result.workers} worker(s), "
          f"{os.cpu_count()} cores")
    print(f"{'stage':<34} {'wall':>8} {'share':>7} {'CPU':>8} {'CPU/wall':>9}")
    for stage, seconds in result.stage_seconds.items():
        cpu = result.stage_cpu_seconds.get(stage, float("nan"))
        ratio = cpu / seconds if seconds > 0 else float("nan")
        print(f"{stage:<34} {seconds:6.1f} s {seconds / total:6.1%} {cpu:6.1f} s {ratio:8.2f}")
    print(f"{'total (with start-up and shut-down)':<34} {total:6.1f} s {'':7} {total_cpu:6.1f} s "
          f"{total_cpu / total:8.2f}")
    print(f"ratio to the {WARM_TARGET_S:.0f} s warm target {total / WARM_TARGET_S:.2f}, "
          f"to the {COLD_TARGET_S:.0f} s first-run target {total / COLD_TARGET_S:.2f}")
    print(f"study store {size_mb:.0f} MB, {result.trials_simulated} trials")
    load_after = os.getloadavg()
    print(f"load average before {load_before[0]:.2f}, after {load_after[0]:.2f} (1 min)\n")
    return total, total_cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--participants", type=int, default=17)
    parser.add_argument("--workers", type=int, help="worker processes (default: one per core)")
    parser.add_argument("--keep", type=Path, help="keep the study directories under DIR/<muscles>")
    parser.add_argument("--profile", type=Path, help="write a cProfile of the parent process here")
    parser.add_argument("--muscles", choices=("simple", "musculoskeletal", "both"), default="simple")
    args = parser.parse_args()
    models: tuple[Literal["simple", "musculoskeletal"], ...] = (
        ("simple", "musculoskeletal") if args.muscles == "both" else (args.muscles,)
    )
    times = {muscles: run_once(args, muscles) for muscles in models}
    if len(times) == 2:
        (wall_s, cpu_s), (wall_m, cpu_m) = times["simple"], times["musculoskeletal"]
        # The study is CPU-bound on 2 cores (docs/study.md): on a shared machine the CPU ratio is the
        # one to scale the documented idle-machine wall time by; the wall ratio counts other load.
        print(f"musculoskeletal / simple: wall {wall_m / wall_s:.3f} ({wall_m:.1f} / {wall_s:.1f} s), "
              f"CPU {cpu_m / cpu_s:.3f} ({cpu_m:.1f} / {cpu_s:.1f} s)")
        estimate_s = DOCUMENTED_SIMPLE_S * cpu_m / cpu_s
        print(f"the simple study's documented {DOCUMENTED_SIMPLE_S:.1f} s warm on an idle machine x the "
              f"CPU ratio: {estimate_s:.1f} s against the {WARM_TARGET_S:.0f} s target")


if __name__ == "__main__":
    main()
