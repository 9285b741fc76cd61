"""Child process of the bench's resume tests: runs (or resumes) a bench protocol on the simulated
bench and says on stdout when each stroke's own motion starts, so the parent can interrupt it there.

Usage: ``bench_child.py RECORDING SPEEDS LOADS REPETITIONS HIGH_DEG POSITION_SPEED [resume]`` (speeds
and loads comma-separated; the strokes go from 20° to HIGH_DEG; POSITION_SPEED is
``BenchRunConfig.position_speed_rad_s``, of the unrecorded moves between strokes).
Prints ``stroke K`` (flushed) as stroke K's spool starts to move, ``done COMPLETE FAULT`` at the end;
a SIGINT is the Ctrl-C of ``bowden bench run``: the run stops safely and reports "interrupted".
"""

from __future__ import annotations

import math
import sys

from bowden.protocol.bench import BenchProtocol
from bowden.runtime.bench import PHASE_STROKE, BenchDevices, BenchRun, BenchRunConfig, BenchSafety
from bowden.runtime.bench_recording import BenchRecordingWriter
from bowden.runtime.realtime import RealtimeConfig, realtime
from bowden.runtime.signals import stop_on_signals
from bowden.sim.backend import open_sim_bench


class AnnouncingClock:
    """The bench's clock, telling the parent when a stroke's motion begins."""

    def __init__(self, clock) -> None:
        self.clock = clock
        self.run: BenchRun | None = None
        self.announced = -1

    def now(self) -> float:
        return self.clock.now()

    def sleep_until(self, deadline_s: float) -> None:
        run = self.run
        if run is not None and run.phase == PHASE_STROKE and run.stroke_under_way is not None:
            index = run.stroke_under_way.index
            if index != self.announced:
                self.announced = index
                print(f"stroke {index}", flush=True)
        self.clock.sleep_until(deadline_s)


def main(path: str, speeds: str, loads: str, repetitions: str, high_deg: str, position_speed: str,
         resume: bool) -> None:
    protocol = BenchProtocol(spool_speeds_rad_s=tuple(map(float, speeds.split(","))),
                             loads_nm=tuple(map(float, loads.split(","))), repetitions=int(repetitions),
                             high_rad=math.radians(float(high_deg)))
    config = BenchRunConfig(protocol=protocol, safety=BenchSafety().on_shared_host(),
                            position_speed_rad_s=float(position_speed))
    with open_sim_bench() as backend:
        clock = AnnouncingClock(backend.clock)
        devices = BenchDevices(tdu=backend.motor, mannequin=backend.mannequin, imu=backend.imu,
                               load_cell=backend.load_cell, clock=clock)
        with BenchRecordingWriter(path, config.protocol_fingerprint(), resume=resume) as writer:
            run = BenchRun(devices, config, writer)
            clock.run = run
            # As `bowden bench run`: stopped by signals even in the background, and the loop under its
            # real-time settings (at normal priority beside the devices' SCHED_FIFO process it fell
            # behind 1 kHz on a slow host, and the lines identified moved by 2-5 %).
            with stop_on_signals(run.request_stop), realtime(RealtimeConfig()):
                report = run.run()
            if report.complete:
                writer.finish()
    print(f"done {report.complete} {report.fault} scouted {run.scouting_moves}", flush=True)


if __name__ == "__main__":
    main(*sys.argv[1:7], resume=len(sys.argv) > 7)
