"""Time each stage of the default `bowden study` (17 participants, the paper's protocol).

Run: python benchmarks/study.py [--participants N] [--workers N] [--keep DIR] [--profile FILE]
Prints wall and CPU seconds per stage (the CPU of the worker processes included) and CPU/wall, the
number of cores a stage kept busy; then the total against the issue's target (≤ 30 s warm on 2 cores,
≤ 60 s for a first run in a fresh venv, compilation included) and the load of the machine (on a
shared machine the wall clock also counts other processes' time; the CPU time does not).
``--profile FILE`` writes a cProfile of this (the parent) process; workers are not profiled.
"""

from __future__ import annotations

import argparse
import cProfile
import os
import tempfile
import time
from pathlib import Path

from bowden.study.pipeline import StudySettings, run_study
from bowden.study.stage_clock import process_tree_cpu

WARM_TARGET_S = 30.0
COLD_TARGET_S = 60.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--participants", type=int, default=17)
    parser.add_argument("--workers", type=int, help="worker processes (default: one per core)")
    parser.add_argument("--keep", type=Path, help="study directory to keep (default: a temporary one)")
    parser.add_argument("--profile", type=Path, help="write a cProfile of the parent process here")
    args = parser.parse_args()
    settings = StudySettings(participants=args.participants)
    load_before = os.getloadavg()
    profiler = cProfile.Profile() if args.profile else None
    with tempfile.TemporaryDirectory() as tmp:
        out = args.keep if args.keep is not None else Path(tmp)
        start, start_cpu = time.perf_counter(), process_tree_cpu()
        if profiler is not None:
            profiler.enable()
        result = run_study(settings, out, force=True, workers=args.workers)
        if profiler is not None:
            profiler.disable()
        total, total_cpu = time.perf_counter() - start, process_tree_cpu() - start_cpu
        size_mb = result.store.stat().st_size / 1e6
    if profiler is not None:
        profiler.dump_stats(args.profile)
    print(f"{args.participants} participants, {result.workers} worker(s), {os.cpu_count()} cores")
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
    print(f"load average before {load_before[0]:.2f}, after {load_after[0]:.2f} (1 min)")


if __name__ == "__main__":
    main()
