"""``bowden run`` with a lab's own condition and speed, and ``bowden analyze`` on a store holding them."""

from __future__ import annotations

import html
import json
import sqlite3
from pathlib import Path

import pandas as pd
import pytest

from bowden.cli import main
from bowden.contracts import BACKEND_SIM
from bowden.model import CompensationModel
from bowden.model.model_file import save_model
from bowden.runtime.recorder import TrialInfo
from bowden.store.study_store import StudyStore

from ..study.test_analyze_contracts import trial_samples

LAB = ["--define-condition", "support_70=0.7", "--define-speed", "V4=240"]


def _run(tmp_path: Path, store: Path, *extra: str) -> int:
    model = tmp_path / "model.json"
    save_model(CompensationModel.from_friction(k=0.12), model)
    return main(["run", "--backend", "sim", "--model", str(model), "--duration", "0.4", "--rate", "250",
                 "--record", str(store), "--participant", "P07", "--lead-in", "0", *extra])


def test_a_custom_condition_and_speed_are_run_and_recorded(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    store = tmp_path / "study.db"
    assert _run(tmp_path, store, *LAB, "--condition", "support_70", "--speed", "V4") == 0
    # The store now knows both names: a later run needs no definitions, and cannot redefine them.
    assert _run(tmp_path, store, "--support", "0.7", "--speed", "V4") == 0
    capsys.readouterr()
    assert _run(tmp_path, store, "--define-condition", "support_70=0.6", "--condition", "support_70") == 1
    assert "condition support_70 is defined as support 0.6 and as support 0.7" in capsys.readouterr().err
    assert _run(tmp_path, store, *LAB, "--condition", "support_70", "--support", "0.6") == 1
    assert "--condition support_70 contradicts --support 0.6: support_70 means --support 0.7" in (
        capsys.readouterr().err)
    assert _run(tmp_path, store, "--condition", "support_80") == 1
    assert "--condition support_80 is unknown" in capsys.readouterr().err
    assert _run(tmp_path, store, "--define-speed", "V5=fast", "--speed", "V5") == 1
    assert "--define-speed: V5's peak must be a number of °/s, got 'fast'" in capsys.readouterr().err
    with sqlite3.connect(store) as connection:
        query = "SELECT condition, speed, support, metadata FROM trials ORDER BY id"
        rows = connection.execute(query).fetchall()
    assert [r[:3] for r in rows] == [("support_70", "V4", 0.7)] * 2
    metadata = json.loads(rows[0][3])
    assert metadata["speed_peak_deg_s"] == 240.0 and metadata["support"] == 0.7
    # The reference ran at V4: a minimum-jerk 80° movement peaking at 240 °/s takes 1.875·80/240 s.
    assert metadata["reference"]["movement_s"] == pytest.approx(1.875 * 80.0 / 240.0)


def _trial(store: StudyStore, participant: str, condition: str, speed: str, support: float,
           peak: float) -> None:
    info = TrialInfo(participant=participant, condition=condition, speed=speed, support=support,
                     metadata={"backend": BACKEND_SIM, "repetitions": 3, "speed_peak_deg_s": peak})
    store.write_trial(info, trial_samples(3))


def test_analyze_reports_custom_conditions_and_speeds_apart_from_the_paper_s_comparisons(
    tmp_path: Path
) -> None:
    path = tmp_path / "study.db"
    with StudyStore(path) as store:
        for participant in ("P01", "P02", "P03"):
            _trial(store, participant, "support_25", "V3", 0.25, 180.0)
            _trial(store, participant, "support_50", "V3", 0.5, 180.0)
            _trial(store, participant, "support_70", "V3", 0.7, 180.0)
            _trial(store, participant, "support_50", "V4", 0.5, 240.0)
        store.write_questionnaires(pd.DataFrame([
            {"participant": p, "condition": c, "questionnaire": "borg_rpe", "item": "rpe", "score": s}
            for p in ("P01", "P02", "P03")
            for c, s in (("support_25", 13), ("support_50", 11), ("support_70", 9))
        ]))
    assert main(["analyze", str(tmp_path), "--quiet"]) == 0
    report = html.unescape((tmp_path / "report.html").read_text(encoding="utf-8"))
    assert "Conditions and speeds beyond the paper" in report
    assert ("Condition support_70 (custom, support 70%): analysed and described under 'Conditions and "
            "speeds beyond the paper'; left out of the paper's comparisons") in report
    assert "Speed V4 (custom, 240 °/s peak): analysed" in report
    with StudyStore(path) as store:
        outcomes = store.outcomes()
    # Every trial is analysed and stored, the custom ones too.
    assert set(outcomes["condition"]) == {"support_25", "support_50", "support_70"}
    assert set(outcomes["speed"]) == {"V3", "V4"}
