"""``bowden bench run --backend sim`` runs the protocol's later segments after the identification
strokes (a shortened protocol: one stroke each way at 1 and at 2 rad/s, a 4 s chirp, one support at
V3 with both compensations): interrupted in the study-like segment it resumes into it, and ``bowden
identify`` and ``bowden bench validate --recording`` take what it recorded (docs/identification.md,
"The protocol, exactly")."""

from __future__ import annotations

import json
import math
import time
from dataclasses import replace

import numpy as np
import pandas as pd

from bowden.cli import main
from bowden.cli._bench_run import bench_model_source
from bowden.protocol.bench import BenchProtocol, LatencyChirp, StudyStrokes
from bowden.runtime.bench import BenchDevices, BenchRun, BenchRunConfig
from bowden.runtime.bench_recording import LATENCY_COLUMNS, STUDY_COLUMNS, BenchRecordingWriter
from bowden.sim.backend import open_sim_bench

SHORT = ["--speeds", "1", "2", "--loads", "1", "--repetitions", "1", "--high-deg", "80", "--chirp-s", "4",
         "--study-supports", "0.5", "--study-speeds", "V3", "--study-repetitions", "3"]


class _Args:  # what bench_model_source reads of the command line
    def __init__(self, output: str) -> None:
        self.output = output
        self.spool_radius = 0.035


def test_the_later_segments_run_resume_and_feed_identify_and_validate(tmp_path, capsys):
    output = tmp_path / "bench.csv"
    config = BenchRunConfig(
        # 20°-80° once each way at two speeds: the dynamic fit tells drag from Coulomb friction only
        # across speeds (at one speed it passed on the steady samples' spread alone, 0.33 of their
        # median against a limit of 0.25, its drag within its standard error: "the model has no
        # dynamic compensation" in one run of two); the 2 rad/s strokes' ramps feed its inertia.
        protocol=BenchProtocol(spool_speeds_rad_s=(1.0, 2.0), loads_nm=(1.0,), repetitions=1,
                               high_rad=math.radians(80.0)),
        latency=LatencyChirp(duration_s=4.0),
        study=StudyStrokes(supports=(0.5,), speeds=("V3",), repetitions=3),
        position_speed_rad_s=2.0,  # the unrecorded moves between strokes (not part of the protocol)
    )
    config = replace(config, safety=config.safety.on_shared_host())  # its devices share this host
    told: list[str] = []

    def announce(text: str) -> None:  # Ctrl-C as the second study-like block starts
        told.append(text)
        if text.startswith("study-like block 2"):
            raise KeyboardInterrupt

    with open_sim_bench() as backend, \
            BenchRecordingWriter(output, config.protocol_fingerprint()) as writer:
        devices = BenchDevices(tdu=backend.motor, mannequin=backend.mannequin, imu=backend.imu,
                               load_cell=backend.load_cell, clock=backend.clock)
        identify = bench_model_source(_Args(str(output)))

        def slow_identify(recording, latency):  # the full protocol's identification takes seconds:
            time.sleep(1.5)  # one more is more than twice the device log's allowed gap below
            return identify(recording, latency)

        report = BenchRun(devices, config, writer, model_source=slow_identify, announce=announce).run()
    # The loop held the arm while the model was identified (a loop that paused would leave both motors
    # on their last command: the simulated mannequin once held its last torque, and the arm drifted out
    # of the range).
    assert report.fault == "interrupted", report.fault
    assert report.strokes_done == 6 and report.strokes_total == 7  # 4 strokes, the chirp, 1 block of 2
    assert "latency chirp" in told[0]
    # Resumed from the command line: only the second block runs.
    code = main(["bench", "run", "--backend", "sim", "-o", str(output), "--resume", *SHORT])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "going on with unit 7" in err and "study-like block 1 of" not in err, err

    # The motors were commanded all along while the model was identified (> 1 s): the device log, a row
    # every 5 ms cycle, has no gap from the chirp to the first study-like block.
    log = pd.read_csv(tmp_path / "bench.log.csv")
    chirp_s, study_s = (log.loc[log["phase"] == phase, "time_s"].iloc[0] for phase in (5, 6))
    between = log[(log["time_s"] >= chirp_s) & (log["time_s"] <= study_s)]
    # (0.55 s once, beside busy processes: the host, not the loop; a loop that paused would leave > 1.5 s.)
    assert between["time_s"].diff().max() < 0.7, between["time_s"].diff().max()
    latency = pd.read_csv(tmp_path / "bench.latency.csv")
    assert tuple(latency.columns) == LATENCY_COLUMNS
    # The chirp's 4 s recorded (rows at 200 Hz of the loop's cycles: fewer when a busy host drops cycles;
    # a stall at its start or end drops rows there: 3.899 s at load average 6, not the 3.995 s idle).
    assert np.ptp(latency["time_s"]) > 3.5 and len(latency) > 200
    # The mannequin's encoder moved the arm along the chirp: ±15° about 60°.
    assert 25.0 < math.degrees(np.ptp(latency["mannequin_elevation_rad"])) < 32.0
    study = pd.read_csv(tmp_path / "bench.study.csv")
    assert tuple(study.columns) == STUDY_COLUMNS
    assert sorted(study["compensation"].unique()) == [0, 1] and (study["speed"] == 3).all()
    assert sorted(study["block"].unique()) == [0, 1]  # the first block once: not run again
    held = study[study["cycle_phase"] >= 1.0]
    # The mannequin followed the study's reference in impedance mode (25 Nm/rad, a wearer's): the cable's
    # error moves the arm by a few degrees. (Its 99th percentile, not its maximum: a host stall leaves
    # the mannequin's command late for a moment, 10.8° once in a fresh clone's three-worker run.)
    follow = np.degrees(np.abs(held["mannequin_elevation_rad"] - held["reference_elevation_rad"]))
    assert follow.mean() < 3.0 and np.percentile(follow, 99) < 10.0, follow.describe()
    assert 70.0 < math.degrees(held["mannequin_elevation_rad"].max()) < 106.0
    # The controller ran: the load cell follows the support law within a few newtons on average.
    rmse = {name: float(np.sqrt(((rows["tension_n"] - rows["law_tension_n"]) ** 2).mean()))
            for name, rows in held.groupby("compensation")}
    assert all(1.0 < value < 15.0 for value in rmse.values()), rmse

    model = tmp_path / "model.json"
    assert main(["identify", str(output), "-o", str(model), "--latency-recording",
                 str(tmp_path / "bench.latency.csv"), "--study-recording",
                 str(tmp_path / "bench.study.csv")]) == 0
    said = capsys.readouterr().out
    assert "IMU latency identified" in said and "recommended:" in said
    dynamic = json.loads(model.read_text())["dynamic"]
    assert [cell["speed"] for cell in dynamic["recommended_cells"]] == ["V3"]
    assert 0.02 < dynamic["imu_latency_s"] < 0.1
    assert main(["bench", "validate", str(model), "--recording", str(tmp_path / "bench.study.csv")]) == 0
    captured = capsys.readouterr()
    table = captured.out
    # bench run's journal keeps no model (it identifies its own during the run): said, not refused.
    assert "could not be checked (bench.csv.journal keeps none" in captured.err, captured.err
    assert "50          V3     paper" in table and "50          V3     dynamic" in table
    # `bench validate --backend sim-wire` runs both compensations again on the bench:
    # tests/runtime/test_bench_fit_sim.py (after its fit; a bench's start costs seconds in this lane).
