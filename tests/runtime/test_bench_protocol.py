"""The default protocol's hazards on the simulated bench over its wire peers (issue 26): every load
step, the fastest lowering under the lightest load, a resume at a fast lowering stroke after SIGKILL
and after SIGINT, a host that stalls or falls behind, a dead load cell. The whole default protocol
(350 strokes, about 25 minutes in real time) runs with ``BOWDEN_NIGHTLY=1``.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bowden.cli import main
from bowden.model.model_file import load_model
from bowden.protocol.bench import BenchProtocol
from bowden.runtime.bench import PHASE_STROKE, BenchDevices, BenchRun, BenchRunConfig, BenchSafety
from bowden.runtime.bench_recording import BenchRecordingWriter
from bowden.sim.backend import open_sim_bench

CHILD = Path(__file__).with_name("bench_child.py")
LOW_DEG, HIGH_DEG = 20.0, 110.0
# How close a stroke must come to its end: half the range margin, as the bench judges it on its 1 kHz
# samples, and a degree for the recording's 200 Hz ones (the IMU's noise is 0.3°).
TOLERANCE_DEG = 6.0


def run(protocol: BenchProtocol, path: Path, *, clock_wrapper=None, inject=None, **config: object):
    # The simulated devices share this (busy) host: its watchdog limits (BenchSafety.on_shared_host).
    config.setdefault("safety", BenchSafety().on_shared_host())
    config_ = BenchRunConfig(protocol=protocol, **config)  # type: ignore[arg-type]
    with open_sim_bench() as backend:
        if inject is not None:
            inject(backend)
        clock = backend.clock if clock_wrapper is None else clock_wrapper(backend.clock)
        devices = BenchDevices(tdu=backend.motor, mannequin=backend.mannequin, imu=backend.imu,
                               load_cell=backend.load_cell, clock=clock)
        with BenchRecordingWriter(path, config_.protocol_fingerprint()) as writer:
            bench = BenchRun(devices, config_, writer)
            if clock_wrapper is not None:
                clock.run = bench
            report = bench.run()
    return report, bench


def assert_every_stroke_covers_the_range(path: Path, protocol: BenchProtocol) -> None:
    frame = pd.read_csv(path)
    low, high = protocol.low_rad, protocol.high_rad
    for stroke in protocol.strokes():
        elevation = np.degrees(frame.loc[frame["trial"] == stroke.index, "elevation_rad"].to_numpy())
        assert elevation.size, stroke
        start = np.median(elevation[:10])  # where the hold began (the bench judges rest on means)
        if stroke.raising:
            assert elevation.max() >= math.degrees(high) - TOLERANCE_DEG, (stroke, elevation.max())
            assert start <= math.degrees(low) + TOLERANCE_DEG, (stroke, start)
        else:
            assert elevation.min() <= math.degrees(low) + TOLERANCE_DEG, (stroke, elevation.min())
            assert start >= math.degrees(high) - TOLERANCE_DEG, (stroke, start)


def test_every_load_step_holds_the_arm_at_the_next_strokes_start(tmp_path):
    # Item 1: the load ramps 2 → 3 → 4 Nm with the arm at the low end, where it sagged below the range
    # guard at 2 → 3 Nm. (The heavy steps and a short range, 20°-45°, keep the test quick; the sag is
    # at the low end under a heavy load.)
    protocol = BenchProtocol(spool_speeds_rad_s=(2.0,), loads_nm=(2.0, 3.0, 4.0), repetitions=1,
                             high_rad=math.radians(45.0))
    report, _ = run(protocol, tmp_path / "steps.csv", position_speed_rad_s=2.0)
    assert report.complete, report.fault
    assert_every_stroke_covers_the_range(tmp_path / "steps.csv", protocol)
    log = pd.read_csv(tmp_path / "steps.log.csv")
    holds = log[log["phase"] == 0]
    assert holds["mannequin_torque_command_nm"].round(3).isin(protocol.loads_nm).all()  # ramped in before


def test_the_fastest_lowering_under_the_lightest_load_covers_the_range(tmp_path):
    # Item 2: −6 rad/s at 0.5 Nm was recorded as complete 50° short of the low end (the light load
    # lowers the arm slower than the spool pays out). Item 3: the first stroke is fast, with nothing
    # learned: a slow move to the high end first (the low end is learned bringing the arm down to the
    # first stroke's start). The raising stroke flings the arm (the cable goes slack as the spool
    # brakes): the mannequin's soft wall stops it before the 120° guard (it reached 120.2° without).
    # The unrecorded moves (the scouting move among them) at 2 rad/s, not 1: 4 s shorter, and 6 rad/s
    # is still a stroke too fast to brake on what the way there showed.
    protocol = BenchProtocol(spool_speeds_rad_s=(6.0,), loads_nm=(0.5,), repetitions=1)
    report, bench = run(protocol, tmp_path / "fast.csv", position_speed_rad_s=2.0)
    assert report.complete, report.fault
    assert bench.scouting_moves >= 1
    assert_every_stroke_covers_the_range(tmp_path / "fast.csv", protocol)
    # Measured: 117.0–118.3° with the wall; 120.0–120.3° without (the guard stops the run at 120°).
    furthest = np.degrees(pd.read_csv(tmp_path / "fast.csv")["elevation_rad"].max())
    assert furthest <= HIGH_DEG + 9.5, furthest


def child(path: Path, options: list[str], *, resume: bool = False) -> subprocess.Popen[str]:
    command = [sys.executable, str(CHILD), str(path), *options, *(["resume"] if resume else [])]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def interrupt_at(process: subprocess.Popen[str], stroke: int, signal_number: int, delay_s: float) -> str:
    """Send ``signal_number`` ``delay_s`` into stroke ``stroke``'s motion; what the child said after
    (everything it said, if it never got there: a fault before, which the caller's assertion shows)."""
    assert process.stdout is not None
    said = []
    for line in process.stdout:
        said.append(line)
        if line.strip() == f"stroke {stroke}":
            time.sleep(delay_s)
            process.send_signal(signal_number)
            said = []
            break
    rest = "".join(said) + process.stdout.read()
    process.wait(timeout=60)
    return rest


def test_a_run_killed_and_interrupted_at_fast_lowering_strokes_resumes_to_the_same_lines(tmp_path, capsys):
    # Item 3 and "Done when": SIGKILL during the −4 rad/s lowering at 1 Nm (stroke 4 of 8), then Ctrl-C
    # during the −4 rad/s lowering at 3 Nm (stroke 8); each resume completes what it can, as informed
    # as the run it continues (no slow move to learn an end again), and the lines identified agree
    # with `bowden bench simulate` within 2 % (measured uninterrupted: slopes within 0.1 %, torque
    # within 1 % over 20–80 N, intercepts within 0.006 Nm). Item 9: the device log stays in time
    # order. (The first resume's −4 rad/s lowering reached 9.8°, past the guard, before the low
    # soft wall; the child said so, and the test's reader, waiting for stroke 7, swallowed it.)
    path = tmp_path / "wire.csv"
    # A range of 20°–70° keeps it quick (the strokes' ends, not their length, are what resumes), and so
    # do the children's unrecorded moves between strokes at 2 rad/s (the last resume's at the
    # command's 1 rad/s: they are not part of the protocol a resume must share).
    options = ["1,4", "1,3", "1", "70", "2"]
    killed = child(path, options)
    said = interrupt_at(killed, 3, signal.SIGKILL, 0.3)
    assert killed.returncode == -signal.SIGKILL, said
    interrupted = child(path, options, resume=True)
    said = interrupt_at(interrupted, 7, signal.SIGINT, 0.3)
    assert "done False interrupted scouted 0" in said, said
    # The last resume through the command line (its path to a complete recording, exit 0).
    same = ["--speeds", "1", "4", "--loads", "1", "3", "--repetitions", "1", "--high-deg", "70"]
    # (The child ran the identification strokes alone: so does the resume.)
    assert main(["bench", "run", "--backend", "sim", "-o", str(path), "--resume", *same,
                 "--no-later-segments"]) == 0, \
        capsys.readouterr().err
    assert "wrote 8 strokes" in capsys.readouterr().out
    protocol = BenchProtocol(spool_speeds_rad_s=(1.0, 4.0), loads_nm=(1.0, 3.0), repetitions=1,
                             high_rad=math.radians(70.0))
    assert_every_stroke_covers_the_range(path, protocol)
    assert pd.read_csv(tmp_path / "wire.log.csv")["time_s"].is_monotonic_increasing

    batch = tmp_path / "batch.csv"
    assert main(["bench", "simulate", "-o", str(batch), "--quiet", *same]) == 0
    for recording in (path, batch):
        assert main(["identify", str(recording), "-o", str(recording.with_suffix(".json"))]) in (0, 3)
    capsys.readouterr()
    wire, simulated = (load_model(p.with_suffix(".json")) for p in (path, batch))
    for direction in ("raising", "lowering"):
        a, b = getattr(wire, direction), getattr(simulated, direction)
        assert a.slope_m == pytest.approx(b.slope_m, rel=0.02), direction
        for tension in (20.0, 40.0, 80.0):
            assert a.intercept_nm + a.slope_m * tension == pytest.approx(
                b.intercept_nm + b.slope_m * tension, rel=0.02), (direction, tension)
        assert a.intercept_nm == pytest.approx(b.intercept_nm, abs=0.015), direction


class StarvedReader:
    """Injected into the simulated bench: once ``starve`` is set, the load cell's reader thread stays
    ``for_s`` in its next I²C transfer, as a thread the host does not schedule (the loop runs on)."""

    def __init__(self, for_s: float) -> None:
        self.for_s = for_s
        self.starve = threading.Event()
        self.done = False

    def __call__(self, backend) -> None:
        bus = backend.load_cell._bus
        read = bus.read_i2c_block_data

        def starving(*args, **kwargs):
            if self.starve.is_set() and not self.done:
                self.done = True
                time.sleep(self.for_s)
            return read(*args, **kwargs)

        bus.read_i2c_block_data = starving


class StallingClock:
    """The bench's clock on a host that falls behind: every cycle 1.5 ms late (no stall), and once,
    during the first stroke, the whole process held for 0.3 s (its threads too: the GIL is kept);
    during the second, the load cell's reader starved (``reader``)."""

    def __init__(self, clock, reader: StarvedReader) -> None:
        self.clock = clock
        self.run: BenchRun | None = None
        self.stalled = False
        self.reader = reader

    def now(self) -> float:
        return self.clock.now()

    def sleep_until(self, deadline_s: float) -> None:
        self.clock.sleep_until(deadline_s)
        time.sleep(0.0015)
        run = self.run
        stroke = run.stroke_under_way if run is not None else None
        if run is not None and run.phase == PHASE_STROKE and stroke is not None and stroke.index == 1:
            self.reader.starve.set()
        if not self.stalled and run is not None and run.phase == PHASE_STROKE:
            self.stalled = True
            interval = sys.getswitchinterval()
            sys.setswitchinterval(1.0)  # no other thread of this process runs: the load cell's reader
            try:
                end = time.monotonic() + 0.3
                while time.monotonic() < end:
                    pass
            finally:
                sys.setswitchinterval(interval)


def test_a_host_that_stalls_or_falls_behind_runs_the_strokes_at_their_speed(tmp_path):
    # Item 7: a reading left old by a stall of the host is not a dead load cell (its age counts from
    # the stall's end, as the IMU's). Item 8: cycles late by 1.5 ms (a loop at 2/5 of its rate) still
    # move the spool at the commanded speed: the target advances by the clock. Item 7's other cause:
    # the load cell's reader starved 0.6 s while the loop runs (it stopped the bench: "no reading for
    # 251 ms") is a gap in the data, not a dead sensor: the stroke is run again, nothing stale is kept.
    protocol = BenchProtocol(spool_speeds_rad_s=(1.0,), loads_nm=(1.0,), repetitions=1,
                             high_rad=math.radians(55.0))
    reader = StarvedReader(0.6)  # a stall of the loop itself meanwhile would hide part of it
    report, _ = run(protocol, tmp_path / "busy.csv", inject=reader,
                    clock_wrapper=lambda clock: StallingClock(clock, reader))
    assert report.complete, report.fault
    assert reader.done and report.data_gaps >= 1, report  # a busy host may starve it more
    frame = pd.read_csv(tmp_path / "busy.csv")
    tension = frame["tension_n"].to_numpy()
    changes = np.flatnonzero(np.diff(tension) != 0.0)
    # A reading is fresh up to 250 ms old (51 rows at 200 Hz); the starved 0.6 s were run again.
    assert np.diff(changes).max() <= 51, "a tension older than the limit was recorded"
    for trial, velocity in ((0, 1.0), (1, -1.0)):
        spool = frame.loc[frame["trial"] == trial, "motor_velocity_rad_s"].to_numpy()
        cruising = spool[np.abs(spool - velocity) < 0.5]  # away from the ramps and the stall
        assert np.median(cruising) == pytest.approx(velocity, rel=0.05), trial


def test_a_dead_load_cell_under_the_lightest_load_is_named_before_the_first_stroke(tmp_path):
    # Item 5: 0 N at 0.5 Nm ran the whole protocol; judged against the tension the load implies, it
    # stops at the first hold, naming the load cell.
    protocol = BenchProtocol(spool_speeds_rad_s=(1.0,), loads_nm=(0.5,), repetitions=1)

    def dead(backend) -> None:
        backend.inject("adc", "override_tension_n", 0.0)

    report, _ = run(protocol, tmp_path / "dead.csv", inject=dead)
    assert report.strokes_done == 0
    assert report.fault is not None, report
    assert report.fault.startswith("the load cell reads 0.0 N while the arm rests"), report.fault


@pytest.mark.skipif(not os.environ.get("BOWDEN_NIGHTLY"), reason="the full default protocol takes about "
                    "35 minutes in real time (its later segments included): set BOWDEN_NIGHTLY=1")
@pytest.mark.timeout(3600)
def test_the_full_default_protocol_completes_and_identifies_as_bench_simulate(tmp_path, capsys):
    wire, batch = tmp_path / "wire.csv", tmp_path / "batch.csv"
    assert main(["bench", "run", "--backend", "sim", "-o", str(wire)]) == 0
    assert main(["bench", "simulate", "-o", str(batch), "--quiet"]) == 0
    assert_every_stroke_covers_the_range(wire, BenchProtocol())
    for recording in (wire, batch):
        assert main(["identify", str(recording), "-o", str(recording.with_suffix(".json"))]) in (0, 3)
    capsys.readouterr()
    a_model, b_model = (load_model(p.with_suffix(".json")) for p in (wire, batch))
    for direction in ("raising", "lowering"):
        a, b = getattr(a_model, direction), getattr(b_model, direction)
        assert a.slope_m == pytest.approx(b.slope_m, rel=0.02), direction
