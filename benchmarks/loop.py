"""Loop timing of ``bowden run --backend sim``: the real drivers against the suit in its own process.

Runs the control loop at 500 Hz and at 1 kHz on the real clock with the default watchdogs and the
default real-time settings of ``bowden run`` (SCHED_FIFO where allowed, no garbage collection in the
loop), the AK60-6 driver on the ``bowden_loopback`` CAN bus, the NGIMU client receiving OSC bundles over
loopback UDP, the ADS1115 reader over the I²C link and the recorder writing a study store, and prints,
per rate, the deadline misses (cycles whose command went out after the next deadline, plus skipped
cycles), the lateness percentiles (p99.9 included), host stalls and the recorder's longest gap between
commits, and the ratio of the late fraction to the goal (issue 14: ≤ 0.05 % at 500 Hz, ≤ 0.1 % at 1 kHz).

    python benchmarks/loop.py [--duration 60] [--rates 500 1000] [--in-process] [--no-realtime]

``--in-process`` runs the device peers as threads of the loop's process (the old setting, for
comparison): every stall of the host is then a stall of the "motor" too.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from bowden.control import build_controller
from bowden.model import CompensationModel, Subject
from bowden.runtime import ControlLoop, LoopConfig, Recorder, TrialInfo
from bowden.runtime.realtime import RealtimeConfig
from bowden.sim.backend import open_sim_backend
from bowden.sim.parameters import SuitParameters

GOALS = {500.0: 0.0005, 1000.0: 0.001}


def run_once(rate_hz: float, duration_s: float, store: Path, *, in_process: bool,
             realtime: RealtimeConfig | None) -> None:
    controller = build_controller(
        model=CompensationModel.from_friction(k=SuitParameters().sheath.kinetic_coefficient),
        support=0.5, subject=Subject(height_m=1.70, mass_kg=63.0, sex="female"),
    )
    trial = TrialInfo(participant="B01", condition="support_50", speed="V1", support=0.5,
                      metadata={"benchmark": "loop", "rate_hz": rate_hz})
    with open_sim_backend(speed="V1", in_process=in_process) as backend, Recorder(store, trial) as recorder:
        loop = ControlLoop(
            controller=controller, motor=backend.motor, elevation_sensor=backend.imu, clock=backend.clock,
            config=LoopConfig(rate_hz=rate_hz, duration_s=duration_s),
            tension_sensor=backend.load_cell, record=recorder.record,
            reference_elevation=backend.reference_elevation,
            recorder_failure=lambda: recorder.failure, on_event=recorder.event, realtime=realtime,
        )
        report = loop.run()
    timing = report.timing
    print(f"{rate_hz:6.0f} Hz | {timing.cycles:7d} cycles | misses {timing.deadline_misses:5d} "
          f"({100.0 * timing.miss_fraction:6.3f} %, {timing.skipped_cycles} skipped) | lateness p50 "
          f"{timing.p50_lateness_s * 1e6:4.0f} µs p99 {timing.p99_lateness_s * 1e6:5.0f} µs "
          f"p99.9 {timing.p999_lateness_s * 1e6:5.0f} µs worst {timing.worst_lateness_s * 1e3:6.2f} ms | "
          f"commit gap max {recorder.stats.max_commit_gap_s * 1e3:.0f} ms | stop: {report.reason}")
    print(f"         {report.describe_health()}; real-time: {report.realtime or 'not asked'}")
    goal = GOALS.get(rate_hz)
    if goal is not None:
        print(f"         goal ≤ {100 * goal:g} % late at {rate_hz:g} Hz: measured "
              f"{100.0 * timing.miss_fraction:.3f} % (ratio to goal {timing.miss_fraction / goal:.2f})")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--duration", type=float, default=60.0, help="seconds per rate (default 60)")
    parser.add_argument("--rates", type=float, nargs="+", default=[500.0, 1000.0])
    parser.add_argument("--in-process", action="store_true", help="device peers as threads of this process")
    parser.add_argument("--no-realtime", action="store_true", help="leave the loop thread's scheduling alone")
    args = parser.parse_args(argv)
    realtime = None if args.no_realtime else RealtimeConfig()
    where = "threads of this process" if args.in_process else "its own process"
    print(f"loop benchmark: {args.duration:g} s per rate, simulated suit in {where}, default watchdogs")
    with tempfile.TemporaryDirectory() as directory:
        for rate in args.rates:
            run_once(rate, args.duration, Path(directory) / f"bench-{rate:g}.db", in_process=args.in_process,
                     realtime=realtime)
    return 0


if __name__ == "__main__":
    sys.exit(main())
