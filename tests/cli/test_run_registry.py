"""``bowden run --participant P07 --record study.db`` runs with the registry's anthropometrics."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import pytest

from bowden.cli import main
from bowden.model import CompensationModel, Subject
from bowden.model.model_file import save_model
from bowden.store.study_store import StudyStore
from bowden.web.registry import Participant, Registry


def _run(tmp_path: Path, store: Path, *extra: str) -> int:
    model = tmp_path / "model.json"
    save_model(CompensationModel.from_friction(k=0.12), model)
    return main(["run", "--backend", "sim", "--model", str(model), "--condition", "support_25",
                 "--duration", "0.4", "--rate", "250", "--record", str(store), "--participant", "P07",
                 "--speed", "V2", "--lead-in", "0", *extra])


def test_a_registered_participant_runs_with_the_registered_anthropometrics(tmp_path: Path) -> None:
    store = tmp_path / "study.db"
    StudyStore(store).close()
    Registry(store).register(Participant(
        participant="P07", subject=Subject(height_m=1.81, mass_kg=77.0, sex="male"), arm_side="left",
        hand_load_kg=1.5, age_years=30,
    ))
    assert _run(tmp_path, store) == 0
    with sqlite3.connect(store) as connection:
        metadata = json.loads(connection.execute("SELECT metadata FROM trials").fetchone()[0])
        query = "SELECT id, height_m, arm_side, hand_load_kg FROM participants"
        registry = connection.execute(query).fetchall()
    assert {k: metadata[k] for k in ("height_m", "mass_kg", "sex", "hand_load_kg")} == {
        "height_m": 1.81, "mass_kg": 77.0, "sex": "male", "hand_load_kg": 1.5
    }
    assert registry == [("P07", 1.81, "left", 1.5)]  # the registration is left as it was


def test_a_flag_that_contradicts_the_registry_is_refused_before_the_suit_opens(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    store = tmp_path / "study.db"
    StudyStore(store).close()
    Registry(store).register(Participant(
        participant="P07", subject=Subject(height_m=1.81, mass_kg=77.0, sex="male"), arm_side="left",
        hand_load_kg=1.5,
    ))
    assert _run(tmp_path, store, "--mass", "60") == 1
    assert "--mass 60.0 contradicts the registry: P07 is registered" in capsys.readouterr().err
    with sqlite3.connect(store) as connection:
        assert connection.execute("SELECT count(*) FROM trials").fetchone()[0] == 0
