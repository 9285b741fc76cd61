"""Custom protocols over HTTP: a lab's own condition (support_70) and speed (V4) in a session plan,
run from the console, answered in the questionnaires, one meaning per name in a store; bad names
refused; a store whose questionnaires table allowed only the paper's conditions migrated."""

from __future__ import annotations

import json
import math
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from starlette.testclient import TestClient

from bowden.cli import build_parser, main
from bowden.cli.serve import session_protocol
from bowden.errors import ParameterError
from bowden.protocol.catalogue import Catalogue, catalogue_of
from bowden.protocol.session_plan import StudyProtocol
from bowden.store.sample_chunks import read_samples
from bowden.store.schema import SCHEMA_VERSION
from bowden.store.study_store import StudyStore
from bowden.web.questionnaire_store import QuestionnaireStore

from .conftest import AUTH, BASE, TOKEN, make_server, registration, trial_request
from .test_sessions import WS, answers, run_next, until

LAB = Catalogue(conditions=(("support_70", 0.7),), speeds=(("V4", 240.0),))
CUSTOM = StudyProtocol(conditions=("support_50", "support_70"), speeds=("V4",), repetitions=1,
                       lead_in_s=0.3, break_s=60.0, catalogue=LAB)


def test_a_plan_with_a_custom_condition_and_speed_runs_from_the_console(tmp_path: Path) -> None:
    web = make_server(tmp_path, protocol=CUSTOM)
    with TestClient(web.app, base_url=BASE) as client:
        options = client.get("/api/options").json()
        conditions = options["conditions"]
        assert {"id": "support_70", "label": "support_70", "support": 0.7, "custom": True} in conditions
        assert {"id": "V4", "peak_deg_s": 240.0, "custom": True} in options["speeds"]
        assert {"id": "support_25", "label": "25% support", "support": 0.25, "custom": False} in conditions
        schema = client.get("/api/questionnaires/schema").json()
        assert {"id": "support_70", "label": "support_70"} in schema["conditions"]

        client.post("/api/participants", headers=AUTH, json=registration("P11"))
        plan = client.post("/api/sessions", headers=AUTH, json={"participant": "P11", "seed": 3}).json()
        assert plan["protocol"]["catalogue"] == {"conditions": {"support_70": 0.7}, "speeds": {"V4": 240.0}}
        assert [s["speed"] for s in plan["steps"]] == ["V4"] * 3
        assert {s["label"] for s in plan["steps"]} == {"no suit", "50% support", "support_70"}
        position = next(s["position"] for s in plan["steps"] if s["condition"] == "support_70")
        early = client.post("/api/questionnaires", headers=AUTH, json=answers("P11", "support_70"))
        assert early.status_code == 409 and "has not run support_70" in early.json()["error"]
        with client.websocket_connect(f"{WS}/ws/console") as console:
            console.send_text(json.dumps({"token": TOKEN}))
            until(console, "session")
            for _ in range(position):
                status = run_next(client, console, plan["session_id"])
                due = status["questionnaire_due"]
                if due != "support_70":  # the conditions before it, answered in their place
                    answered = client.post("/api/questionnaires", headers=AUTH, json=answers("P11", due))
                    assert answered.status_code == 201
        assert status["steps"][position - 1]["state"] == "done"
        assert status["questionnaire_due"] == "support_70"
        stored = client.post("/api/questionnaires", headers=AUTH, json=answers("P11", "support_70"))
        assert stored.status_code == 201, stored.text

        # One rule outside the plan too: the condition's support, a known name.
        contradicting = client.post("/api/trial/start", headers=AUTH,
                                    json=trial_request(participant="P11", condition="support_70",
                                                       speed="V4", support=0.6))
        assert contradicting.status_code == 400
        assert "support_70 means support 0.7" in contradicting.json()["error"]
        unknown = client.post("/api/trial/start", headers=AUTH,
                              json=trial_request(participant="P11", condition="support_80"))
        assert unknown.status_code == 400 and "condition" in unknown.json()["error"]

    with sqlite3.connect(web.config.store_path) as connection:
        trial_id, support, speed, metadata = connection.execute(
            "SELECT id, support, speed, metadata FROM trials WHERE condition = 'support_70'").fetchone()
        samples = read_samples(connection, trial_id)
        reference = samples["reference_elevation_rad"].to_numpy()
        times = samples["time_s"].to_numpy()
        rpe = connection.execute("SELECT score FROM questionnaires WHERE condition = 'support_70' "
                                 "AND questionnaire = 'borg_rpe'").fetchone()
    assert support == 0.7 and speed == "V4" and rpe == (12,)
    assert json.loads(metadata)["speed_peak_deg_s"] == 240.0 and json.loads(metadata)["support"] == 0.7
    # The reference the participant followed peaked at V4's 240 °/s (not V1's 60, the fallback).
    peak = math.degrees(float(np.max(np.abs(np.gradient(reference, times)))))
    assert peak == pytest.approx(240.0, rel=0.03)


def test_a_name_keeps_one_meaning_in_a_store(tmp_path: Path) -> None:
    web = make_server(tmp_path, protocol=CUSTOM)
    with TestClient(web.app, base_url=BASE) as client:
        client.post("/api/participants", headers=AUTH, json=registration("P12"))
        started = client.post("/api/trial/start", headers=AUTH, json=trial_request(
            participant="P12", condition="support_70", speed="V4", height_m=1.7, mass_kg=63.0))
        assert started.status_code == 201, started.text
        with client.websocket_connect(f"{WS}/ws/console") as console:
            console.send_text(json.dumps({"token": TOKEN}))
            until(console, "stopped")
    other = Catalogue(conditions=(("support_70", 0.6),))
    with pytest.raises(ParameterError, match=r"support_70 is defined as support 0.6 and as support 0.7"):
        make_server(tmp_path, protocol=StudyProtocol(conditions=("support_70",), catalogue=other))
    # A server without the definitions still knows the store's own (recorded with the trial).
    again = make_server(tmp_path)
    assert again.desk.catalogue.support("support_70") == 0.7
    assert again.desk.catalogue.peak_deg_s("V4") == 240.0


@pytest.mark.parametrize(("definition", "message"), [
    ("support 70=0.7", "condition name 'support 70' is not allowed: use a letter, then"),
    ("70pct=0.7", "condition name '70pct' is not allowed"),
    ("support_25=0.3", "condition support_25 is the paper's (support 0.25): give yours another name"),
    ("support_70=1.7", "support must be a fraction in (0, 1]"),
    ("support_70", "expected NAME=VALUE such as support_70=0.7"),
])
def test_bad_condition_definitions_are_refused_in_one_line(definition: str, message: str) -> None:
    with pytest.raises(ParameterError, match=r"^--define-condition: ") as refused:
        catalogue_of([definition], None)
    assert message in str(refused.value) and "\n" not in str(refused.value)


def test_serve_flags_make_the_protocol_and_name_the_flag(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = build_parser().parse_args([
        "serve", "--define-condition", "support_70=70%", "--define-speed", "V4=240",
        "--conditions", "pretension,support_70", "--speeds", "V1,V4"])
    protocol = session_protocol(args)
    assert protocol.catalogue == LAB and protocol.conditions == ("pretension", "support_70")
    assert protocol.speeds == ("V1", "V4")
    for flags, text in ((["--define-speed", "V 4=240"], "--define-speed: speed name 'V 4' is not allowed"),
                        (["--define-speed", "V1=90"], "speed V1 is the paper's (60 °/s)"),
                        (["--define-speed", "V4=900"], "the peak must be 10–400 °/s"),
                        (["--conditions", "support_70"], "--conditions: unknown condition(s) support_70"),
                        (["--speeds", "V4"], "--speeds must be distinct speeds")):
        code = main(["serve", "--store", str(tmp_path / "study.db"), "--port", "0", *flags])
        assert code == 1
        assert text in capsys.readouterr().err


def test_an_older_store_s_questionnaires_table_is_migrated_and_keeps_its_answers(tmp_path: Path) -> None:
    path = tmp_path / "study.db"
    old_check = "CHECK (condition IN ('no_suit', 'pretension', 'support_25', 'support_50'))"
    with sqlite3.connect(path) as connection:  # the layout of schema 2, with one answer in it
        connection.execute("PRAGMA user_version=2")
        connection.execute(f"""CREATE TABLE questionnaires (
            participant TEXT NOT NULL, condition TEXT NOT NULL {old_check},
            questionnaire TEXT NOT NULL, item TEXT NOT NULL, score INTEGER NOT NULL,
            submitted_utc TEXT NOT NULL, PRIMARY KEY (participant, condition, questionnaire, item)) STRICT""")
        connection.execute("INSERT INTO questionnaires VALUES ('P01', 'support_25', 'borg_rpe', 'rpe', 13, "
                           "'2024-01-01T00:00:00')")
        with pytest.raises(sqlite3.IntegrityError):
            connection.execute("INSERT INTO questionnaires VALUES ('P01', 'support_70', 'borg_rpe', 'rpe', "
                               "9, '2024-01-01T00:00:00')")
    QuestionnaireStore(path)  # opening migrates
    with StudyStore(path) as store:  # the study store opens it too, and migrates nothing twice
        kept = store.questionnaires()
        store.write_questionnaires(answers_frame("support_70"))
        after = store.questionnaires()
    assert list(kept[["participant", "condition", "score"]].itertuples(index=False, name=None)) == [
        ("P01", "support_25", 13)]
    assert set(after["condition"]) == {"support_25", "support_70"}
    with sqlite3.connect(path) as connection:
        tables = [r[0] for r in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
        sql = connection.execute("SELECT sql FROM sqlite_master WHERE name = 'questionnaires'").fetchone()[0]
        version = connection.execute("PRAGMA user_version").fetchone()[0]
    assert "condition IN (" not in sql and "questionnaires_migrated" not in tables
    assert version == SCHEMA_VERSION


def answers_frame(condition: str):
    import pandas as pd

    return pd.DataFrame([{"participant": "P01", "condition": condition, "questionnaire": "borg_rpe",
                          "item": "rpe", "score": 9}])
