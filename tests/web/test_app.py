"""The HTTP API and WebSockets through starlette's TestClient, with trials on the simulated suit."""

import json
import math
import re
import sqlite3

import pytest
from starlette.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from bowden.contracts import FATIGUE_SITES, NORDIC_SITES
from bowden.control import Fault
from bowden.runtime import LoopState
from bowden.store.sample_chunks import read_samples
from bowden.web.app import STATIC_DIR

from .conftest import AUTH, BASE, TOKEN, store_snapshot, trial_request

WS = "ws://127.0.0.1"


def answers(participant="P02", condition="support_25", exception="checking the form, no trial run"):
    """A full submission; by default marked as an exception (these tests run no trial first)."""
    body = {
        "participant": participant,
        "condition": condition,
        "nordic": {site: 2 for site in NORDIC_SITES},
        "borg_rpe": 13,
        "fatigue": {site: 3 for site in FATIGUE_SITES},
    }
    if exception is not None:
        body["exception"] = exception
    return body


def until(ws, kind):
    """Messages from a socket up to and including the first of type ``kind``."""
    seen = []
    while True:
        message = ws.receive_json()
        seen.append(message)
        if message["type"] == kind:
            return seen


@pytest.mark.parametrize("path", ["/", "/display", "/console", "/questionnaire"])
def test_pages_are_served_with_a_strict_content_security_policy(client, path):
    response = client.get(path)
    assert response.status_code == 200 and "text/html" in response.headers["content-type"]
    policy = response.headers["content-security-policy"]
    assert "default-src 'self'" in policy and "script-src 'self'" in policy
    assert response.headers["x-frame-options"] == "DENY"
    for asset in re.findall(r'(?:src|href)="([^"]+)"', response.text):
        assert asset.startswith("/"), f"{path} refers to {asset} outside this server"


def test_every_asset_is_local(client):
    files = sorted(STATIC_DIR.iterdir())
    expected = {"display.js", "console.js", "questionnaire.js", "common.js", "style.css"}
    assert {f.name for f in files} >= expected
    for path in files:
        text = path.read_text(encoding="utf-8")
        assert not re.search(r"https?://|//cdn|@import", text), f"{path.name} fetches from elsewhere"
        assert client.get(f"/static/{path.name}").status_code == 200


def test_public_endpoints_change_nothing_and_reveal_no_ids(client, web):
    before = store_snapshot(web.config.store_path)
    options = client.get("/api/options").json()
    assert [c["id"] for c in options["conditions"]] == ["no_suit", "pretension", "support_25", "support_50"]
    assert client.get("/api/status").json() == {"type": "trial", "state": "idle"}
    assert client.get("/api/questionnaires/schema").status_code == 200
    assert store_snapshot(web.config.store_path) == before


def test_other_host_names_are_refused(web):
    with TestClient(web.app, base_url="http://attacker.example") as other:
        assert other.get("/api/status").status_code == 400


@pytest.mark.parametrize(
    "headers", [{}, {"X-Bowden-Token": "wrong-token-wrong-token"}, {"Authorization": f"Bearer {TOKEN}x"}]
)
def test_operator_actions_without_the_token_are_refused_and_change_nothing(client, web, headers):
    path = web.config.store_path
    client.post("/api/questionnaires", headers=AUTH, json=answers())  # something in the store
    before = store_snapshot(path)
    refused = [
        client.post("/api/trial/start", headers=headers, json=trial_request()),
        client.post("/api/trial/stop", headers=headers, json={}),
        client.post("/api/questionnaires", headers=headers, json=answers("P03")),
        client.post("/api/questionnaires", headers=headers, json={**answers(), "replace": True}),
        client.post("/api/questionnaires", headers=headers, data={"participant": "P03", "token": "nope"}),
        client.get("/api/questionnaires", headers=headers),
        client.get("/api/console/status", headers=headers),
    ]
    for response in refused:
        assert response.status_code == 403, response.text
        assert "nothing was changed" in response.json()["error"]
    assert store_snapshot(path) == before
    assert not web.manager.running and web.manager.trials_run == 0


def test_invalid_requests_are_refused_and_change_nothing(client, web):
    path = web.config.store_path
    client.post("/api/questionnaires", headers=AUTH, json=answers())
    before = store_snapshot(path)
    bad_answers = answers("P05")
    bad_answers["nordic"]["hips"] = 9
    cases = [
        (client.post("/api/questionnaires", headers=AUTH, json=bad_answers), 400, "nordic.hips"),
        (client.post("/api/questionnaires", headers=AUTH, json=answers()), 409, "already stored"),
        (client.post("/api/questionnaires", headers=AUTH, json=answers("Bob")), 400, "participant"),
        (client.post("/api/trial/start", headers=AUTH, json=trial_request(participant="Alice")), 400,
         "participant"),
        (client.post("/api/trial/start", headers=AUTH, json=trial_request(speed="fast")), 400, "speed"),
        (client.post("/api/trial/stop", headers=AUTH, json={}), 409, "no trial is running"),
        (client.post("/api/trial/start", headers=AUTH, content=b"{", ), 415, "application/json"),
        (client.post("/api/trial/start", headers={**AUTH, "Content-Type": "application/json"},
                     content=b"[1]"), 400, "JSON object"),
        (client.post("/api/questionnaires", headers={**AUTH, "Content-Type": "application/json"},
                     content=b'{"a": "' + b"x" * 40000 + b'"}'), 413, "bytes"),
    ]
    for response, status, words in cases:
        assert response.status_code == status, response.text
        assert words in response.json()["error"]
    assert store_snapshot(path) == before
    assert web.manager.trials_run == 0


def test_questionnaires_by_json_and_by_form(client, web):
    stored = client.post("/api/questionnaires", headers=AUTH, json=answers("P07", "no_suit"))
    assert stored.status_code == 201 and stored.json()["stored"] == 23
    form = {"participant": "P07", "condition": "pretension", "borg_rpe": "15", "token": TOKEN,
            "exception": "checking the form, no trial run"}
    form.update({f"nordic.{s}": "1" for s in NORDIC_SITES})
    form.update({f"fatigue.{s}": "7" for s in FATIGUE_SITES})
    assert client.post("/api/questionnaires", data=form).status_code == 201
    rows = client.get("/api/questionnaires", headers=AUTH, params={"participant": "P07"}).json()["rows"]
    assert len(rows) == 46
    assert ["P07", "pretension", "borg_rpe", "rpe", 15] in [r[:5] for r in rows]
    nordic = [r for r in web.questionnaires.rows("P07", "no_suit") if r[2] == "nordic"]
    assert len(nordic) == 16 and {r[4] for r in nordic} == {2}
    assert client.get("/api/questionnaires", headers=AUTH, params={"participant": "Eve"}).status_code == 400


def test_the_console_socket_needs_the_token(client):
    with client.websocket_connect(f"{WS}/ws/console") as ws:
        ws.send_text(json.dumps({"token": "wrong-wrong-wrong-wrong"}))
        assert ws.receive_json()["type"] == "error"
        with pytest.raises(WebSocketDisconnect) as closed:
            ws.receive_json()
        assert closed.value.code == 1008
    with client.websocket_connect(f"{WS}/ws/console") as ws:
        ws.send_text(json.dumps({"token": TOKEN}))
        hello = ws.receive_json()
        assert hello["type"] == "trial" and hello["backend"] == "sim"


def test_sockets_from_other_sites_are_refused(client):
    with pytest.raises(WebSocketDisconnect), client.websocket_connect(
        f"{WS}/ws/display", headers={"Origin": "http://evil.example"}
    ) as ws:
        ws.receive_json()


def test_a_simulated_trial_streams_to_the_display_and_is_recorded(client, web):
    with client.websocket_connect(f"{WS}/ws/display") as display:
        assert display.receive_json() == {"type": "trial", "state": "idle"}
        started = client.post("/api/trial/start", headers=AUTH, json=trial_request())
        assert started.status_code == 201
        trial_id = started.json()["trial_id"]
        # A second start while running is a conflict and changes nothing.
        assert client.post("/api/trial/start", headers=AUTH, json=trial_request()).status_code == 409
        messages = until(display, "stopped")
    text = json.dumps(messages)
    assert "P01" not in text and "participant" not in text  # the display never learns who it is
    samples = [m for m in messages if m["type"] == "samples"]
    shown = {t: el for m in samples for t, el in zip(m["t"], m["elevation_deg"], strict=True)}
    with sqlite3.connect(web.config.store_path) as connection:
        rows = read_samples(connection, trial_id)
        stored = {round(t, 4): math.degrees(el)
                  for t, el in zip(rows["time_s"], rows["elevation_rad"], strict=True)}
        reason = connection.execute("SELECT stop_reason FROM trials WHERE id = ?", (trial_id,)).fetchone()[0]
    assert len(shown) == pytest.approx(len(stored) / 2.5, abs=2)  # 250 Hz loop thinned to 100 Hz
    for t, elevation in shown.items():
        assert elevation == pytest.approx(stored[t], abs=1e-3)
    assert reason.startswith("duration")
    assert not web.manager.running


def test_the_stop_button_puts_the_suit_in_the_safe_state(client, web):
    with client.websocket_connect(f"{WS}/ws/console") as console:
        console.send_text(json.dumps({"token": TOKEN}))
        console.receive_json()
        long_trial = trial_request(repetitions=10, speed="V1")
        started = client.post("/api/trial/start", headers=AUTH, json=long_trial)
        trial_id = started.json()["trial_id"]
        until(console, "samples")
        assert client.post("/api/trial/stop", headers=AUTH, json={}).status_code == 200
        result = until(console, "stopped")[-1]
    assert result["faults"] == [Fault.STOP_REQUESTED.name]
    assert result["motor_disabled"] is True and result["reason"] == "operator stop (console)"
    assert result["clean"] is True  # an operator stop is a clean end, not a watchdog fault
    with sqlite3.connect(web.config.store_path) as connection:
        rows = list(read_samples(connection, trial_id).loc[:, ["controller_state", "commanded_torque_nm"]]
                    .itertuples(index=False, name=None))
        events = connection.execute("SELECT kind FROM events WHERE trial_id = ?", (trial_id,)).fetchall()
    assert rows[-1] == (int(LoopState.RAMPING_DOWN), 0.0)  # the ramp ended at zero torque
    assert any(state == int(LoopState.RAMPING_DOWN) for state, _ in rows)
    assert ("safe_stop",) in events
    health = client.get("/api/console/status", headers=AUTH).json()
    assert health["state"] == "idle" and health["last_result"]["trial_id"] == trial_id


def test_shutting_the_server_down_stops_a_running_trial(web):
    with TestClient(web.app, base_url=BASE) as client:
        client.post("/api/trial/start", headers=AUTH, json=trial_request(repetitions=10, speed="V1"))
        assert web.manager.running
    assert not web.manager.running
    assert web.manager.last_result is not None
    assert web.manager.last_result["reason"] == "server shutting down"


class FreezingImu:
    """The simulated IMU until ``freeze_s``, then its last sample forever (a stalled OSC stream)."""

    def __init__(self, imu, freeze_s):
        self.imu, self.freeze_s, self.frozen = imu, freeze_s, None

    def read(self):
        if self.frozen is not None:
            return self.frozen
        sample = self.imu.read()
        if sample is not None and sample.time_s >= self.freeze_s:
            self.frozen = sample
        return sample

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return None


def test_a_watchdog_fault_reaches_the_console_and_the_store(tmp_path):
    from contextlib import contextmanager

    from bowden.model import CompensationModel
    from bowden.web.server import ServeConfig, build_server
    from bowden.web.suits import ContextBackend, OpenSuit, SimulatedBackend

    @contextmanager
    def stalling_suit(setup):
        suit = SimulatedBackend(time_scale=20.0).open(setup)
        suit.elevation_sensor = FreezingImu(suit.elevation_sensor, freeze_s=0.5)
        try:
            yield OpenSuit(motor=suit.motor, elevation_sensor=suit.elevation_sensor, clock=suit.clock,
                           tension_sensor=suit.tension_sensor, description="stalling IMU")
        finally:
            suit.close()

    config = ServeConfig(store_path=tmp_path / "study.sqlite", model=CompensationModel.from_friction(k=0.12),
                         backend=ContextBackend("stall", stalling_suit), token=TOKEN, rate_hz=250.0)
    web = build_server(config)
    with TestClient(web.app, base_url=BASE) as client, \
            client.websocket_connect(f"{WS}/ws/console") as console:
        console.send_text(json.dumps({"token": TOKEN}))
        console.receive_json()
        trial_id = client.post("/api/trial/start", headers=AUTH, json=trial_request()).json()["trial_id"]
        result = until(console, "stopped")[-1]
    assert result["clean"] is False and result["faults"] == [Fault.IMU_STALE.name]
    assert result["reason"].startswith("IMU: newest sample") and result["motor_disabled"] is True
    with sqlite3.connect(config.store_path) as connection:
        flags = int(read_samples(connection, trial_id)["fault_flags"].max())
        events = connection.execute("SELECT kind FROM events WHERE trial_id = ?", (trial_id,)).fetchall()
    assert flags & int(Fault.IMU_STALE) and ("fault",) in events


def test_a_suit_that_cannot_be_opened_is_a_clear_refusal(tmp_path):
    from bowden.errors import HardwareError
    from bowden.model import CompensationModel
    from bowden.web.server import ServeConfig, build_server

    class Unplugged:
        name = "can"

        def open(self, setup):
            raise HardwareError("no CAN interface can0: is the adapter plugged in?")

    config = ServeConfig(store_path=tmp_path / "study.sqlite", model=CompensationModel.from_friction(k=0.12),
                         backend=Unplugged(), token=TOKEN)
    web = build_server(config)
    with TestClient(web.app, base_url=BASE) as client:
        before = store_snapshot(config.store_path)
        response = client.post("/api/trial/start", headers=AUTH, json=trial_request())
        assert response.status_code == 503 and "can0" in response.json()["error"]
        assert not web.manager.running
        assert store_snapshot(config.store_path) == before
        assert client.post("/api/trial/stop", headers=AUTH, json={}).status_code == 409
