"""Throughput of `bowden sweep` on a local Dask cluster with 1 and with 2 workers, measured in one run.

Run: python benchmarks/sweep.py [--points N] [--participants N]
Prints points per second for each cluster size and the speed-up of 2 workers over 1 (ideal 2.0 on two
free cores). Each measurement is a fresh sweep directory on a cluster that is already up and warm
(a first task per worker compiles nothing: numba caches on disk, but imports cost ≈ 1 s), so the
ratio is the scaling of the task graph, not of start-up. The identification is shared (one suit).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np
from distributed import Client, LocalCluster

from bowden.sweep import SweepSpec, run_sweep
from bowden.sweep import axes as ax


def measure(spec: SweepSpec, workers: int) -> float:
    """Points per second of ``spec`` on a warm local cluster of ``workers`` processes."""
    with (
        LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        Client(cluster) as client,
        tempfile.TemporaryDirectory() as warm_dir,
        tempfile.TemporaryDirectory() as out,
    ):
        warm = SweepSpec(
            name="warm", axes=((ax.BLEND_99, (0.5,)),), participants=2, repetitions=2, speeds=("V3",),
            conditions=("support_50",), bench="quick",
        )
        run_sweep(warm, warm_dir, client)  # imports and first calls on every worker
        start = time.perf_counter()
        run_sweep(spec, out, client)
        seconds = time.perf_counter() - start
    return len(spec.points()) / seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=6, help="blend configurations in the sweep")
    parser.add_argument("--participants", type=int, default=3)
    args = parser.parse_args()
    spec = SweepSpec(
        name="benchmark",
        axes=((ax.BLEND_99, tuple(float(v) for v in np.linspace(0.1, 2.0, args.points))),),
        participants=args.participants,
        bench="quick",
    )
    print(
        f"{len(spec.points())} points × {spec.participants} participants × "
        f"{len(spec.conditions) * len(spec.speeds)} trials of {spec.repetitions} cycles"
    )
    # 1, 2, 2, 1: a load that drifts during the run biases both sizes alike.
    rates: dict[int, list[float]] = {1: [], 2: []}
    for workers in (1, 2, 2, 1):
        rates[workers].append(measure(spec, workers))
    for workers, measured in rates.items():
        rate = float(np.mean(measured))
        tasks = rate * spec.participants
        print(f"{workers} worker(s): {rate:6.3f} points/s  ({tasks:6.2f} participant-tasks/s)")
    ratio = np.mean(rates[2]) / np.mean(rates[1])
    load = os.getloadavg()[0]
    print(f"speed-up of 2 workers over 1: {ratio:.2f} (ideal 2.00 on two free cores)")
    print(f"load average (1 min) at the end: {load:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
