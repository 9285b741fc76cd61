"""A console trial records which model it ran with: the file, its SHA-256, the coefficients and the
compensation, as ``bowden run`` and ``bowden study`` do (issue 27, item 10)."""

from __future__ import annotations

import hashlib
import json
import sqlite3
from pathlib import Path

from starlette.testclient import TestClient

from bowden.model import CompensationModel
from bowden.model.model_file import load_model, save_model
from bowden.store.schema import STORE_FILE_NAME
from bowden.web.server import ServeConfig, build_server
from bowden.web.suits import SimulatedBackend

from .conftest import AUTH, BASE, SHORT_PROTOCOL, TOKEN, trial_request
from .test_app import WS, until


def test_a_console_trial_records_its_model_file_hash_and_coefficients(tmp_path: Path) -> None:
    path = tmp_path / "model.json"
    save_model(CompensationModel.from_friction(k=0.12), path)
    config = ServeConfig(store_path=tmp_path / STORE_FILE_NAME, model=load_model(path), model_file=path,
                         backend=SimulatedBackend(time_scale=20.0), token=TOKEN, rate_hz=250.0,
                         protocol=SHORT_PROTOCOL)
    web = build_server(config)
    with TestClient(web.app, base_url=BASE) as client, client.websocket_connect(
        f"{WS}/ws/display"
    ) as display:
        display.receive_json()
        started = client.post("/api/trial/start", headers=AUTH, json=trial_request())
        assert started.status_code == 201, started.text
        until(display, "stopped")
    with sqlite3.connect(config.store_path) as connection:
        (text,) = connection.execute("SELECT metadata FROM trials WHERE id = ?",
                                     (started.json()["trial_id"],)).fetchone()
    metadata = json.loads(text)
    assert metadata["model"] == str(path)
    assert metadata["model_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert metadata["model_coefficients"]["raising"]["slope_m"] == load_model(path).raising.slope_m
    assert metadata["compensation"] == "paper"
