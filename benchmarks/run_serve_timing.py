"""Loop timing of ``bowden run --serve``: does serving the browsers cost the control loop its deadlines?

Runs the loop of ``bowden run --backend sim`` (real drivers against the simulated suit's wire peers,
the recorder writing a study store) in turn: ``plain``; ``server``, with the web server of
``--serve`` attached (its own thread and event loop, the rows handed over through the non-blocking
tap) but no browser; and ``browsers``, the same with a participant display and an operator console
connected from another process on this machine and receiving every batch. Prints, per run, the late
cycles (deadline misses and skipped cycles), the lateness percentiles and what the browsers received;
then the late cycles of each mode over all its runs and their ratios to plain. Goal: serving leaves
the loop within issue 5's ≤ 1 % late cycles at 500 Hz.

On the lab's setup the browsers usually run on other computers (the participant's screen, the
operator's laptop); the ``browsers`` mode, with both on the loop's two cores, is the pessimistic case.

    python benchmarks/run_serve_timing.py [--duration 20] [--rate 500] [--rounds 2]

The watchdogs are lenient (500 ms) so that a descheduled process ends no run early: the measurement
spans the whole duration.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from bowden.control import build_controller
from bowden.model import CompensationModel, Subject
from bowden.runtime import ControlLoop, LoopConfig, LoopReport, Recorder, Row, SafetyConfig, TrialInfo
from bowden.sim.backend import open_sim_backend
from bowden.web.server import ServeConfig, ServerThread
from bowden.web.suits import CommandLineBackend, OpenSuit
from bowden.web.trial_setup import TrialSetup, study_reference

# The browsers: a display and a console (with the token), counting what they receive until the end.
BROWSERS = r"""
import json, sys, threading
from websockets.sync.client import connect
url, token = sys.argv[1], sys.argv[2]
counts = {"display": [0, 0], "console": [0, 0]}  # sample messages, samples
def watch(role):
    with connect(url.replace("http", "ws") + "/ws/" + role, open_timeout=10) as ws:
        if role == "console":
            ws.send(json.dumps({"token": token}))
        for text in ws:
            message = json.loads(text)
            if message["type"] == "samples":
                counts[role][0] += 1
                counts[role][1] += len(message["t"])
            elif message["type"] == "stopped":
                return
threads = [threading.Thread(target=watch, args=(role,)) for role in counts]
for thread in threads: thread.start()
print("connected", flush=True)
for thread in threads: thread.join(120)
print(json.dumps(counts), flush=True)
"""

SUBJECT = Subject(height_m=1.70, mass_kg=63.0, sex="female")
SAFETY = SafetyConfig(imu_max_age_s=0.5, motor_max_silence_s=0.5)


MODES = ("plain", "server", "browsers")


def run_once(rate_hz: float, duration_s: float, store: Path, mode: str) -> tuple[LoopReport, str]:
    served = mode != "plain"
    model = CompensationModel.from_friction(k=0.12)
    reference = study_reference("V1", lead_in_s=1.0, repetitions=max(1, int((duration_s - 1.0) / 5.0)))
    setup = TrialSetup(participant="P99", condition="support_50", speed="V1", support=0.5,
                       repetitions=reference.repetitions, lead_in_s=reference.start_s, subject=SUBJECT)
    trial = TrialInfo(participant="P99", condition="support_50", speed="V1", support=0.5,
                      metadata={"benchmark": "run_serve_timing", "served": served})
    controller = build_controller(model=model, support=0.5, subject=SUBJECT)
    config = ServeConfig(store_path=store, model=model, backend=CommandLineBackend("sim"), port=0,
                         rate_hz=rate_hz, safety=SAFETY)
    server = ServerThread(config) if served else None
    browsers = None
    received = ""
    try:
        if server is not None:
            server.__enter__()
        if server is not None and mode == "browsers":
            browsers = subprocess.Popen([sys.executable, "-c", BROWSERS, server.url, server.web.token.value],
                                        stdout=subprocess.PIPE, text=True)
            assert browsers.stdout is not None and browsers.stdout.readline().strip() == "connected"
        with open_sim_backend(reference=reference) as backend, Recorder(store, trial) as recorder:
            loop = ControlLoop(
                controller=controller, motor=backend.motor, elevation_sensor=backend.imu, clock=backend.clock,
                config=LoopConfig(rate_hz=rate_hz, duration_s=duration_s, safety=SAFETY),
                tension_sensor=backend.load_cell, reference_elevation=backend.reference_elevation,
            )
            record = recorder.record
            if server is not None:
                suit = OpenSuit(motor=backend.motor, elevation_sensor=backend.imu, clock=backend.clock,
                                tension_sensor=backend.load_cell, description=backend.describe)
                tap = server.web.manager.attach(setup, suit, loop, recorder)

                def both(row: Row) -> None:
                    record(row)
                    tap(row)

                loop.record = both
            else:
                loop.record = record
            report = loop.run()
        if server is not None:
            server.web.manager.detach(report)
        if browsers is not None:
            out, _ = browsers.communicate(timeout=30)
            counts = json.loads(out.strip().splitlines()[-1])
            received = (f" | display got {counts['display'][1]} samples in {counts['display'][0]} messages, "
                        f"console {counts['console'][1]} in {counts['console'][0]}")
    finally:
        if browsers is not None and browsers.poll() is None:
            browsers.kill()
            browsers.wait()
        if server is not None:
            server.__exit__(None, None, None)
    return report, received


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--duration", type=float, default=20.0, help="seconds per run (default 20)")
    parser.add_argument("--rate", type=float, default=500.0, help="control rate (default 500 Hz)")
    parser.add_argument("--rounds", type=int, default=2, help="rounds of the three modes (default 2)")
    args = parser.parse_args(argv)
    late = {mode: [0, 0] for mode in MODES}  # late cycles, scheduled cycles
    with tempfile.TemporaryDirectory() as directory:
        for k in range(args.rounds * len(MODES)):
            mode = MODES[k % len(MODES)]
            report, received = run_once(args.rate, args.duration, Path(directory) / f"run{k}.db", mode)
            timing = report.timing
            late[mode][0] += timing.deadline_misses
            late[mode][1] += timing.cycles + timing.skipped_cycles
            print(f"{mode:8s} | {timing.cycles:6d} cycles | late "
                  f"{timing.deadline_misses:5d} ({100.0 * timing.miss_fraction:5.2f} %, "
                  f"{timing.skipped_cycles} skipped) | lateness p50 {timing.p50_lateness_s * 1e6:4.0f} µs "
                  f"p99 {timing.p99_lateness_s * 1e6:5.0f} µs worst {timing.worst_lateness_s * 1e3:6.2f} ms"
                  f"{received} | stop: {report.reason}", flush=True)
    fraction = {mode: late[mode][0] / max(1, late[mode][1]) for mode in MODES}
    plain = fraction["plain"]
    print(f"late cycles at {args.rate:g} Hz: " + ", ".join(
        f"{mode} {100.0 * fraction[mode]:.2f} % (/ goal 1 % = {fraction[mode] / 0.01:.2f}, / plain = "
        f"{fraction[mode] / plain if plain else float('inf'):.2f})" for mode in MODES))
    return 0


if __name__ == "__main__":
    sys.exit(main())
