"""Time the identification of a full bench recording against the 5 s budget of issue 4.

The recording follows the paper's protocol ("Data acquisition"): spool speeds ±0.5, 1, 2, 3, 4, 5,
6 rad/s over 20°–110°, loads 0.5, 1, 2, 3, 4 Nm, five repetitions. It comes from the simulated bench
(``bowden.sim``) when that provides one, otherwise from the single-bend transmission law of the
identification tests (same size and structure). Each stage is timed separately and end to end from
a CSV and a Parquet file (median of ``--repeats`` runs); the ratios are time / 5 s budget.

Run: python benchmarks/identify.py [--rate-hz 500] [--repeats 3]
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from bowden.identify import (
    LOWERING,
    RAISING,
    TransmissionIdentifier,
    bench_filter,
    bench_recording_from_frame,
    bench_select,
    read_bench_recording,
    robustfit,
    save_identification_figure,
)

BUDGET_S = 5.0
PAPER_SPEEDS_RAD_S = (0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
PAPER_LOADS_NM = (0.5, 1.0, 2.0, 3.0, 4.0)


def law_recording(rate_hz: float) -> pd.DataFrame:
    """The paper's full protocol generated from the transmission law (tests/identify/law_bench.py)."""
    # Loaded by path: a site-packages "tests" package may shadow the repository's tests directory.
    path = Path(__file__).resolve().parents[1] / "tests" / "identify" / "law_bench.py"
    spec = importlib.util.spec_from_file_location("law_bench", path)
    if spec is None or spec.loader is None:
        raise SystemExit(f"cannot load {path}")
    module = importlib.util.module_from_spec(spec)
    sys.modules["law_bench"] = module  # dataclasses look their module up while being defined
    spec.loader.exec_module(module)
    return module.law_bench_frame(
        spool_speeds_rad_s=PAPER_SPEEDS_RAD_S,
        loads_nm=PAPER_LOADS_NM,
        repetitions=5,
        rate_hz=rate_hz,
        noise_tension_n=0.5,
        noise_torque_nm=0.02,
        outlier_fraction=0.001,
    )


def simulated_recording() -> pd.DataFrame | None:
    """The simulated bench's full paper protocol (``bowden.sim.bench.run_bench``), when available."""
    try:
        from bowden.sim.bench import run_bench
    except ImportError:
        return None
    return run_bench()


def median_time(fn: Callable[[], object], repeats: int) -> float:
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate-hz", type=float, default=500.0, help="sampling rate of the law recording")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--law", action="store_true", help="use the law recording even if bowden.sim exists")
    args = parser.parse_args()

    frame = None if args.law else simulated_recording()
    source = "simulated bench, paper protocol (bowden.sim.bench.run_bench)"
    if frame is None:
        frame = law_recording(args.rate_hz)
        source = f"transmission-law recording at {args.rate_hz:g} Hz"
    if "trial" in frame:
        spans = frame.groupby("trial")["time_s"].agg(["min", "max"])
        duration_s = float((spans["max"] - spans["min"]).sum())
    else:
        duration_s = float(frame["time_s"].iloc[-1] - frame["time_s"].iloc[0])
    print(f"recording: {source}, {len(frame)} samples, {duration_s / 60:.1f} min of bench time")

    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "bench.csv"
        parquet = Path(tmp) / "bench.parquet"
        frame.to_csv(csv, index=False)
        frame.to_parquet(parquet)
        recording = read_bench_recording(parquet)
        filtered = bench_filter(recording)
        selection = bench_select(filtered)
        identifier = TransmissionIdentifier().fit(recording)
        fits = {RAISING: identifier.raising_fit_, LOWERING: identifier.lowering_fit_}
        stages = {
            "read + validate CSV": lambda: read_bench_recording(csv),
            "read + validate Parquet": lambda: read_bench_recording(parquet),
            "validate in-memory table": lambda: bench_recording_from_frame(frame),
            "filter (per segment)": lambda: bench_filter(recording),
            "select steady state": lambda: bench_select(filtered),
            "robustfit raising": lambda: robustfit(
                selection.tension_n(RAISING), selection.motor_torque_nm(RAISING)
            ),
            "robustfit lowering": lambda: robustfit(
                selection.tension_n(LOWERING), selection.motor_torque_nm(LOWERING)
            ),
            "figure (PNG)": lambda: save_identification_figure(selection, fits, Path(tmp) / "fig.png"),
            "END TO END from CSV": lambda: TransmissionIdentifier().fit(csv),
            "END TO END from Parquet": lambda: TransmissionIdentifier().fit(parquet),
        }
        print(f"{'stage':<28}{'median s':>10}{'/ 5 s budget':>14}")
        for name, fn in stages.items():
            elapsed = median_time(fn, args.repeats)
            print(f"{name:<28}{elapsed:>10.3f}{elapsed / BUDGET_S:>14.3f}")
    summary = identifier.summary_
    print(
        f"identified: raising n={summary.raising.n} slope {1e3 * summary.raising.slope_m:.3f} mm, "
        f"lowering n={summary.lowering.n} slope {1e3 * summary.lowering.slope_m:.3f} mm, k={summary.k}"
    )


if __name__ == "__main__":
    main()
