"""The console's pre-flight (``GET /api/console/preflight``): the checks of ``bowden check`` on the
suit ``bowden serve`` was started with. The simulated suit's IMU streams in real time, so this file is
in the real-time group of tests/conftest.py."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from starlette.testclient import TestClient

from bowden.cli import build_parser
from bowden.cli.serve import serve_config
from bowden.web.security import TOKEN_HEADER
from bowden.web.server import build_server

from .conftest import BASE, TOKEN, make_server


def test_the_console_runs_the_checks_of_the_served_suit(tmp_path: Path) -> None:
    args = build_parser().parse_args(["serve", "--store", str(tmp_path / "study.sqlite"),
                                      "--calibration-s", "0.3"])
    config = replace(serve_config(args), token=TOKEN)
    with TestClient(build_server(config).app, base_url=BASE) as client:
        assert client.get("/api/console/preflight").status_code == 403  # the token is needed
        response = client.get("/api/console/preflight", headers={TOKEN_HEADER: TOKEN})
    assert response.status_code == 200, response.text
    report = response.json()
    assert [check["name"] for check in report["checks"]] == ["can", "motor", "imu", "load_cell", "store"]
    assert report["ok"], report
    assert "study.sqlite writable" in report["checks"][-1]["message"]


def test_a_server_without_a_preflight_says_so(tmp_path: Path) -> None:
    with TestClient(make_server(tmp_path).app, base_url=BASE) as client:
        response = client.get("/api/console/preflight", headers={TOKEN_HEADER: TOKEN})
    assert response.status_code == 400 and "no pre-flight" in response.json()["error"]


def test_the_console_page_has_the_preflight_panel(tmp_path: Path) -> None:
    with TestClient(make_server(tmp_path).app, base_url=BASE) as client:
        page = client.get("/console").text
        script = client.get("/static/console_preflight.js").text
    assert 'id="preflight-run"' in page and "/static/console_preflight.js" in page
    assert "/api/console/preflight" in script
