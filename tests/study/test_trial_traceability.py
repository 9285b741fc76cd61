"""Every outcome row and every trial traceable (issue 27, item 10): outcomes name their trial, trials
record their model's hash and coefficients, the report lists the trials' stops and compensation."""

from __future__ import annotations

import hashlib
import json
import math
import sqlite3
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bowden.cli import main
from bowden.contracts import BACKEND_SIM, TRIAL_COLUMNS
from bowden.model import CompensationModel
from bowden.model.model_file import save_model
from bowden.model.model_record import model_coefficients, model_sha256
from bowden.protocol import MinimumJerkCycle
from bowden.runtime.recorder import TrialInfo
from bowden.store.study_store import StudyStore
from bowden.study.analyze import analyze_store
from bowden.study.trial_list import id_ranges, trial_list

RATE_HZ = 100.0
CYCLE = MinimumJerkCycle(peak_speed_rad_s=math.radians(180.0))  # V3: one cycle in 5/3 s
KEY = ["participant", "condition", "speed", "repetition", "phase", "measure"]
MODEL = CompensationModel.from_friction(k=0.12)
IMU_STOP = "IMU: newest sample 51 ms old (limit 50 ms)"


def trial_samples(cycles: int = 3, lead_s: float = 0.5) -> pd.DataFrame:
    """``cycles`` V3 cycles between rests; the suit tracks the desired tension within 1 N."""
    time = np.arange(0.0, 2 * lead_s + cycles * CYCLE.period_s, 1.0 / RATE_HZ)
    moving = (time >= lead_s) & (time <= lead_s + cycles * CYCLE.period_s)
    reference = np.where(moving, CYCLE.elevation_rad(np.clip(time - lead_s, 0.0, None)), CYCLE.low_rad)
    desired = 20.0 + 30.0 * np.sin(reference)
    return pd.DataFrame({
        "time_s": time, "reference_elevation_rad": reference, "elevation_rad": reference,
        "elevation_velocity_rad_s": np.gradient(reference, time), "desired_tension_n": desired,
        "moment_arm_m": np.full(time.size, 0.05), "commanded_torque_nm": 0.02 * desired,
        "motor_torque_nm": 0.02 * desired, "motor_velocity_rad_s": np.zeros(time.size),
        "tension_n": desired + np.sin(7.0 * time), "controller_state": np.ones(time.size, dtype=int),
        "fault_flags": np.zeros(time.size, dtype=int),
    }).loc[:, list(TRIAL_COLUMNS)]


@pytest.fixture(scope="module")
def analysed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """Five trials, two of them P01 support_50 V3 (repeated, as a lab does after a problem)."""
    directory = tmp_path_factory.mktemp("traceable")
    store_path = directory / "study.db"
    recorded = {"backend": BACKEND_SIM, "repetitions": 3, "compensation": "paper", "model": "lab/model.json",
                "model_sha256": model_sha256(MODEL), "model_coefficients": model_coefficients(MODEL)}
    trials = [("P01", "support_50", IMU_STOP), ("P01", "support_50", "duration 9 s reached"),
              ("P01", "support_25", "duration 9 s reached"), ("P02", "support_50", "duration 9 s reached"),
              ("P02", "support_25", "duration 9 s reached")]
    with StudyStore(store_path) as store:
        for participant, condition, stop in trials:
            support = 0.5 if condition == "support_50" else 0.25
            info = TrialInfo(participant=participant, condition=condition, speed="V3", support=support,
                             metadata=recorded)
            store.write_trial(info, trial_samples(), stop_reason=stop)
    analyze_store(store_path, directory / "report.html", workers=1)
    return store_path, directory / "report.html"


def test_each_outcome_row_names_its_trial(analysed: tuple[Path, Path], tmp_path: Path) -> None:
    store_path, _report = analysed
    with StudyStore(store_path) as store:
        outcomes = store.outcomes()
        store.export(tmp_path / "export", file_format="csv")
    # Without the trial, trials 1 and 2 give the same keys (the 76 duplicates in a 5-trial store).
    assert outcomes.duplicated(KEY).sum() > 0
    assert not outcomes.duplicated([*KEY, "trial_id"]).any()
    assert sorted(set(outcomes["trial_id"])) == [1, 2, 3, 4, 5]
    repeated = outcomes[(outcomes["participant"] == "P01") & (outcomes["condition"] == "support_50")]
    assert sorted(set(repeated["trial_id"])) == [1, 2]
    exported = pd.read_csv(tmp_path / "export" / "outcomes.csv")
    assert list(exported.columns[:5]) == ["participant", "condition", "speed", "trial_id", "repetition"]
    assert not exported.duplicated([*KEY, "trial_id"]).any()
    assert len(exported) == len(outcomes)


def test_the_report_lists_the_trials_stops_and_compensation(analysed: tuple[Path, Path]) -> None:
    _store, report = analysed
    text = report.read_text(encoding="utf-8")
    assert '<h2 id="trials">Trials</h2>' in text and '<a href="#trials">Trials</a>' in text  # in the contents
    section = text[text.index('<h2 id="trials">Trials</h2>'):text.index('<h2 id="methods">Methods</h2>')]
    short = model_sha256(MODEL)[:12]
    # The odd stop stands alone with the trial's name; the four alike trials are one row.
    assert IMU_STOP in section and "#1 P01 support_50 V3" in section
    assert "duration 9 s reached" in section and "#2–#5" in section
    assert section.count(f"{short} (lab/model.json)") == 2 and section.count(">paper<") == 2


def test_the_trial_list_groups_alike_trials() -> None:
    metadata = json.dumps({"compensation": None})
    trials = pd.DataFrame({
        "id": [1, 2, 3, 4, 5, 7], "participant": ["P01"] * 6, "condition": ["no_suit"] * 6,
        "speed": ["V1"] * 6, "stop_reason": ["completed"] * 5 + [None], "metadata": [metadata] * 5 + ["{}"],
    })
    table = trial_list(trials)
    assert table.to_dict("records") == [
        {"stop reason": "completed", "compensation": "none (no controller)",
         "model (SHA-256)": "not recorded", "trials": 5, "which": "#1–#5"},
        {"stop reason": "not recorded", "compensation": "not recorded", "model (SHA-256)": "not recorded",
         "trials": 1, "which": "#7 P01 no_suit V1"},
    ]
    assert id_ranges([9, 1, 2, 3, 5, 6]) == "#1–#3, #5–#6, #9"


def test_bowden_run_records_the_models_hash_and_coefficients(tmp_path: Path) -> None:
    model_path, store = tmp_path / "model.json", tmp_path / "study.db"
    save_model(MODEL, model_path)
    with model_path.open("a") as file:
        file.write("\n")  # a lab's file need not be byte for byte what bowden writes: its own hash counts
    assert main(["run", "--backend", "sim", "--model", str(model_path), "--condition", "support_25",
                 "--duration", "0.4", "--rate", "250", "--record", str(store), "--participant", "P07",
                 "--speed", "V2", "--lead-in", "0"]) == 0
    with sqlite3.connect(store) as connection:
        metadata = json.loads(connection.execute("SELECT metadata FROM trials").fetchone()[0])
    assert metadata["model"] == str(model_path)
    assert metadata["model_sha256"] == hashlib.sha256(model_path.read_bytes()).hexdigest()
    assert metadata["model_coefficients"] == model_coefficients(MODEL)
    assert metadata["model_coefficients"]["raising"]["slope_m"] == MODEL.raising.slope_m
    assert metadata["compensation"] == "paper"


def test_an_older_outcome_table_gains_the_trial_column(tmp_path: Path) -> None:
    path = tmp_path / "study.db"
    StudyStore(path).close()
    with sqlite3.connect(path) as connection:  # the table as schema 5 made it, with a row
        connection.execute("DROP TABLE outcomes")
        connection.execute("CREATE TABLE outcomes (participant TEXT NOT NULL, condition TEXT NOT NULL, "
                           "speed TEXT NOT NULL, repetition INTEGER NOT NULL, phase TEXT NOT NULL, "
                           "measure TEXT NOT NULL, value REAL) STRICT")
        connection.execute("INSERT INTO outcomes VALUES ('P01', 'no_suit', 'V1', 2, 'entire', 'sparc', -2.5)")
        connection.execute("PRAGMA user_version=5")
    connection.close()
    with StudyStore(path) as store:
        outcomes = store.outcomes()
    assert list(outcomes.columns[:4]) == ["participant", "condition", "speed", "trial_id"]
    assert outcomes["trial_id"].isna().all() and outcomes["value"].tolist() == [-2.5]
