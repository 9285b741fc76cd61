"""The registry and the session plan over HTTP: register once, follow the plan, questionnaires in their
place, redo and skip with reasons, and a restarted server resuming from the store."""

from __future__ import annotations

import json
import sqlite3

from starlette.testclient import TestClient

from bowden.contracts import FATIGUE_SITES, NORDIC_SITES
from bowden.protocol.session_plan import condition_order, williams_square

from .conftest import (
    AUTH,
    BASE,
    SHORT_PROTOCOL,
    TOKEN,
    make_server,
    registration,
    store_snapshot,
    trial_request,
)

WS = "ws://127.0.0.1"


def answers(participant: str, condition: str, **extra: object) -> dict[str, object]:
    return {"participant": participant, "condition": condition, "nordic": {s: 2 for s in NORDIC_SITES},
            "borg_rpe": 12, "fatigue": {s: 3 for s in FATIGUE_SITES}, **extra}


def until(ws, kind):
    seen = []
    while True:
        message = ws.receive_json()
        seen.append(message)
        if message["type"] == kind:
            return seen


def run_next(client, console, session_id):
    """Start the plan's next trial, wait for its end; the session status that follows it."""
    started = client.post(f"/api/sessions/{session_id}/next", headers=AUTH, json={})
    assert started.status_code == 201, started.text
    until(console, "stopped")
    return client.get(f"/api/sessions/{session_id}", headers=AUTH).json()


def test_a_participant_is_registered_once_and_never_overwritten(client, web):
    created = client.post("/api/participants", headers=AUTH, json=registration("P07"))
    assert created.status_code == 201 and created.json()["registered"] is True
    again = client.post("/api/participants", headers=AUTH, json=registration("P07"))
    assert again.status_code == 200 and again.json()["registered"] is False
    before = store_snapshot(web.config.store_path)
    changed = client.post("/api/participants", headers=AUTH, json=registration("P07", mass_kg=70.0))
    assert changed.status_code == 409 and "mass_kg" in changed.json()["error"]
    for bad, field in ((registration(" P03 "), "participant"), (registration("P01\n"), "participant"),
                       (registration(arm_side="both"), "arm_side"), (registration(height_m=170), "height_m"),
                       (registration(name="Anna"), "unknown field")):
        refused = client.post("/api/participants", headers=AUTH, json=bad)
        assert refused.status_code == 400 and field in refused.json()["error"], refused.text
    assert store_snapshot(web.config.store_path) == before
    listed = client.get("/api/participants", headers=AUTH).json()["participants"]
    assert listed == [{"participant": "P07", "height_m": 1.7, "mass_kg": 63.0, "sex": "female",
                       "arm_side": "right", "hand_load_kg": 0.5, "age_years": 27}]


def test_the_plan_is_drawn_from_a_recorded_seed_and_stored_before_the_first_trial(client, web):
    refused = client.post("/api/sessions", headers=AUTH, json={"participant": "P08"})
    assert refused.status_code == 409 and "not registered" in refused.json()["error"]
    client.post("/api/participants", headers=AUTH, json=registration("P08"))
    opened = client.post("/api/sessions", headers=AUTH, json={"participant": "P08", "seed": 1234})
    assert opened.status_code == 201
    plan = opened.json()
    expected = condition_order(SHORT_PROTOCOL, seed=1234, sequence=0)
    assert expected[0] == "no_suit" and plan["condition_order"] == list(expected)
    assert [s["condition"] for s in plan["steps"]] == list(expected)  # one speed: one trial a condition
    assert plan["next"] == 1 and plan["progress"] == {"done": 0, "skipped": 0, "total": 4}
    with sqlite3.connect(web.config.store_path) as connection:
        stored = connection.execute("SELECT seed, condition_order FROM sessions").fetchall()
        steps = connection.execute("SELECT count(*) FROM plan_steps").fetchone()[0]
        trials = connection.execute("SELECT count(*) FROM trials").fetchone()[0]
    assert stored == [(1234, json.dumps(list(expected)))] and steps == 4 and trials == 0
    # Asking again resumes the same session rather than drawing another.
    again = client.post("/api/sessions", headers=AUTH, json={"participant": "P08", "seed": 99})
    assert again.status_code == 200 and again.json()["session_id"] == plan["session_id"]


def test_the_pages_call_the_paper_conditions_in_words(client):
    # The paper's table heads ("no", "pre") read as words in the console's sentences.
    client.post("/api/participants", headers=AUTH, json=registration("P13"))
    plan = client.post("/api/sessions", headers=AUTH, json={"participant": "P13"}).json()
    words = {"no_suit": "no suit", "pretension": "pretension", "support_25": "25% support",
             "support_50": "50% support"}
    assert {s["condition"]: s["label"] for s in plan["steps"]} == words
    for listed in (client.get("/api/options").json(), client.get("/api/questionnaires/schema").json()):
        assert {c["id"]: c["label"] for c in listed["conditions"]} == words


def test_latin_square_sessions_take_the_rows_in_turn(tmp_path):
    from dataclasses import replace

    web = make_server(tmp_path, protocol=replace(SHORT_PROTOCOL, order="latin_square"))
    with TestClient(web.app, base_url=BASE) as client:
        orders = []
        for k in range(1, 4):
            client.post("/api/participants", headers=AUTH, json=registration(f"P{k}"))
            orders.append(client.post("/api/sessions", headers=AUTH, json={"participant": f"P{k}"}).json())
    support = SHORT_PROTOCOL.conditions
    rows = williams_square(len(support))
    for k, plan in enumerate(orders):
        assert plan["sequence"] == k
        assert plan["condition_order"] == ["no_suit", *(support[i] for i in rows[k])]


def test_a_session_runs_its_plan_with_questionnaires_in_their_place(client, web):
    client.post("/api/participants", headers=AUTH, json=registration("P09", hand_load_kg=1.0))
    plan = client.post("/api/sessions", headers=AUTH, json={"participant": "P09", "seed": 5}).json()
    session, order = plan["session_id"], plan["condition_order"]
    with client.websocket_connect(f"{WS}/ws/console") as console:
        console.send_text(json.dumps({"token": TOKEN}))
        until(console, "session")  # a console that connects is shown the session at once
        # Questionnaires for a condition not run are refused, and nothing is stored.
        early = client.post("/api/questionnaires", headers=AUTH, json=answers("P09", order[1]))
        assert early.status_code == 409 and "has not run" in early.json()["error"]
        status = run_next(client, console, session)
        assert status["steps"][0]["state"] == "done" and status["next"] == 2
        assert status["questionnaire_due"] == order[0]
        assert status["break"]["condition"] == order[0] and status["break"]["length_s"] == 60.0
        stored = client.post("/api/questionnaires", headers=AUTH, json=answers("P09", order[0]))
        assert stored.status_code == 201
        status = client.get(f"/api/sessions/{session}", headers=AUTH).json()
        assert status["questionnaire_due"] is None and status["questionnaires_answered"] == [order[0]]
        # An exception, with its reason, lets the operator store answers for a condition not run.
        excepted = client.post("/api/questionnaires", headers=AUTH,
                               json=answers("P09", order[3], exception="participant leaves early"))
        assert excepted.status_code == 201
        # Redo: the completed trial is kept and marked; the step runs again.
        first_trial = status["steps"][0]["trial_id"]
        redo = client.post(f"/api/sessions/{session}/redo", headers=AUTH,
                           json={"position": 1, "reason": "cuff slipped"})
        assert redo.status_code == 200 and redo.json()["next"] == 1
        status = run_next(client, console, session)
        attempts = status["steps"][0]["attempts"]
        assert attempts[0] == {"trial_id": first_trial, "status": "redone", "reason": "cuff slipped"}
        assert attempts[1]["status"] == "completed"
        assert status["steps"][0]["trial_id"] == attempts[1]["trial_id"]
        # Skip needs a reason; the reason is recorded.
        no_reason = client.post(f"/api/sessions/{session}/skip", headers=AUTH,
                                json={"position": 2, "reason": ""})
        assert no_reason.status_code == 400 and "reason" in no_reason.json()["error"]
        skipped = client.post(f"/api/sessions/{session}/skip", headers=AUTH,
                              json={"position": 2, "reason": "motor too warm"})
        assert skipped.json()["steps"][1]["state"] == "skipped" and skipped.json()["next"] == 3
    with sqlite3.connect(web.config.store_path) as connection:
        metadata = json.loads(connection.execute(
            "SELECT metadata FROM trials WHERE id = ?", (attempts[1]["trial_id"],)).fetchone()[0])
        query = "SELECT kind, condition, reason FROM session_notes ORDER BY rowid"
        notes = connection.execute(query).fetchall()
    # The trial ran with the registered anthropometrics and says which step of which plan it was.
    assert metadata["hand_load_kg"] == 1.0 and metadata["height_m"] == 1.7 and metadata["arm_side"] == "right"
    assert metadata["session_id"] == session and metadata["plan_position"] == 1 and metadata["plan_seed"] == 5
    assert notes == [("questionnaire_exception", order[3], "participant leaves early"),
                     ("skip", order[1], "motor too warm")]


def test_a_training_trial_outside_the_plan_does_not_count_as_the_planned_condition(client, web):
    client.post("/api/participants", headers=AUTH, json=registration("P11"))
    plan = client.post("/api/sessions", headers=AUTH, json={"participant": "P11", "seed": 3}).json()
    planned = plan["condition_order"][1]
    training = trial_request(participant="P11", condition=planned)
    with client.websocket_connect(f"{WS}/ws/console") as console:
        console.send_text(json.dumps({"token": TOKEN}))
        until(console, "session")
        assert client.post("/api/trial/start", headers=AUTH, json=training).status_code == 201
        assert until(console, "stopped")[-1]["completed"] is True
    before = store_snapshot(web.config.store_path)
    refused = client.post("/api/questionnaires", headers=AUTH, json=answers("P11", planned))
    assert refused.status_code == 409, refused.text
    assert refused.json()["error"].startswith(f"P11 has not run {planned} in the session plan (")
    assert store_snapshot(web.config.store_path) == before
    status = client.get(f"/api/sessions/{plan['session_id']}", headers=AUTH).json()
    assert status["questionnaire_due"] is None and status["progress"]["done"] == 0


def test_without_a_session_plan_a_trial_run_elsewhere_lets_its_questionnaire_in(client, web):
    # bowden run --record (or a console trial) with no plan for the participant: the trial counts.
    trial = trial_request(participant="P12", condition="support_25")
    with client.websocket_connect(f"{WS}/ws/console") as console:
        console.send_text(json.dumps({"token": TOKEN}))
        assert client.post("/api/trial/start", headers=AUTH, json=trial).status_code == 201
        until(console, "stopped")
    stored = client.post("/api/questionnaires", headers=AUTH, json=answers("P12", "support_25"))
    assert stored.status_code == 201
    refused = client.post("/api/questionnaires", headers=AUTH, json=answers("P12", "support_50"))
    assert refused.status_code == 409 and "P12 has not run support_50:" in refused.json()["error"]


def test_a_restarted_server_resumes_the_session_and_marks_the_interrupted_trial(tmp_path):
    web = make_server(tmp_path, time_scale=1.0)
    with TestClient(web.app, base_url=BASE) as client:
        client.post("/api/participants", headers=AUTH, json=registration("P10"))
        session = client.post("/api/sessions", headers=AUTH, json={"participant": "P10"}).json()["session_id"]
        assert client.post(f"/api/sessions/{session}/next", headers=AUTH, json={}).status_code == 201
        running = client.get(f"/api/sessions/{session}", headers=AUTH).json()
        assert running["running"] == 1
    # The server went down mid-trial (its shutdown stops the trial safely); a new one resumes.
    again = make_server(tmp_path, token="another-token-0123456789")
    with TestClient(again.app, base_url=BASE) as client:
        status = client.get("/api/sessions/current", headers={"X-Bowden-Token": "another-token-0123456789"})
    resumed = status.json()
    assert resumed["session_id"] == session and resumed["next"] == 1 and resumed["running"] is None
    attempt = resumed["steps"][0]["attempts"][0]
    assert attempt["status"] == "stopped" and attempt["reason"] == "server shutting down"


def test_a_trial_outside_the_plan_takes_the_registry_s_anthropometrics(client, web):
    client.post("/api/participants", headers=AUTH, json=registration("P11", mass_kg=80.0))
    body = {"participant": "P11", "condition": "support_25", "speed": "V3", "repetitions": 1,
            "lead_in_s": 0.3}
    contradicting = client.post("/api/trial/start", headers=AUTH, json={**body, "mass_kg": 63.0})
    assert contradicting.status_code == 400 and "mass_kg: P11 is registered with 80.0" in contradicting.text
    started = client.post("/api/trial/start", headers=AUTH, json=body)
    assert started.status_code == 201 and started.json()["setup"]["mass_kg"] == 80.0
