"""Fixtures of the web tests: a server application on the simulated suit, its token, its store."""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from pathlib import Path

import pytest
from starlette.testclient import TestClient

from bowden.model import CompensationModel
from bowden.web.server import ServeConfig, WebServer, build_server
from bowden.web.suits import SimulatedBackend

TOKEN = "test-token-0123456789abcdef"
AUTH = {"X-Bowden-Token": TOKEN}
BASE = "http://127.0.0.1"


def trial_request(**changes: object) -> dict[str, object]:
    """A valid start request for a short simulated trial."""
    body: dict[str, object] = {
        "participant": "P01", "condition": "support_50", "speed": "V3", "repetitions": 1,
        "lead_in_s": 0.3, "height_m": 1.70, "mass_kg": 63.0, "sex": "female",
    }
    body.update(changes)
    return body


def store_snapshot(path: Path) -> dict[str, list[tuple[object, ...]]]:
    """Every row of every table of the study store (to show a refused request changed nothing)."""
    if not path.exists():
        return {}
    with sqlite3.connect(path) as connection:
        tables = [r[0] for r in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
        return {t: sorted(connection.execute(f"SELECT * FROM {t}").fetchall(), key=repr) for t in tables}


def make_server(tmp_path: Path, *, time_scale: float = 20.0, rate_hz: float = 250.0) -> WebServer:
    config = ServeConfig(
        store_path=tmp_path / "study.sqlite",
        model=CompensationModel.from_friction(k=0.12),
        backend=SimulatedBackend(time_scale=time_scale),
        token=TOKEN,
        rate_hz=rate_hz,
    )
    return build_server(config)


@pytest.fixture
def web(tmp_path: Path) -> WebServer:
    return make_server(tmp_path)


@pytest.fixture
def client(web: WebServer) -> Iterator[TestClient]:
    with TestClient(web.app, base_url=BASE) as test_client:
        yield test_client
