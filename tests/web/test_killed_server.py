"""``bowden serve`` killed (SIGKILL) mid-trial: the restarted server resumes the session, and
``bowden analyze DIR`` finds the store under the one name and names the trial left open."""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx2 as httpx  # what the dev extra installs (starlette's TestClient uses it too)
import pytest

from bowden.cli import build_parser, main
from bowden.store.sample_chunks import sample_count
from bowden.store.schema import STORE_FILE_NAME
from bowden.store.sessions import LEFT_OPEN

from .conftest import registration

SERVE = ["--port", "0", "--time-scale", "4", "--rate-hz", "250", "--speeds", "V3", "--repetitions", "1",
         "--lead-in", "0.3"]
START_TIMEOUT_S = 60.0  # a loaded machine starts Python slowly; nothing asserts on time


def test_serve_writes_the_store_analyze_looks_for() -> None:
    assert build_parser().parse_args(["serve"]).store == Path(STORE_FILE_NAME)


@contextmanager
def serving(store: Path) -> Iterator[tuple[str, dict[str, str], subprocess.Popen[str]]]:
    """``bowden serve`` in a process of its own; its URL and token read from what it prints."""
    process = subprocess.Popen(
        [sys.executable, "-u", "-m", "bowden", "serve", "--store", str(store), *SERVE],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
    )
    try:
        url = token = None
        assert process.stdout is not None
        while token is None:
            line = process.stdout.readline()
            assert line, "bowden serve ended before printing its addresses"
            if line.startswith("bowden serve: "):
                url = line.split()[2]
            elif "session token:" in line:
                token = line.split()[-1]
        assert url is not None
        yield url, {"X-Bowden-Token": token}, process
    finally:
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
            process.wait(30)


def _samples(store: Path, trial_id: int) -> int:
    with sqlite3.connect(store) as connection:
        return sample_count(connection, trial_id)


def test_a_killed_server_s_open_trial_is_resumed_and_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    store = tmp_path / STORE_FILE_NAME
    with serving(store) as (url, auth, process):
        http = httpx.Client(base_url=url, headers=auth, timeout=START_TIMEOUT_S)
        assert http.post("/api/participants", json=registration("P05")).status_code == 201
        session = http.post("/api/sessions", json={"participant": "P05", "seed": 3}).json()["session_id"]
        first = http.post(f"/api/sessions/{session}/next", json={}).json()["trial_id"]
        while http.get(f"/api/sessions/{session}").json()["steps"][0]["state"] != "done":
            time.sleep(0.1)
        second = http.post(f"/api/sessions/{session}/next", json={}).json()["trial_id"]
        while _samples(store, second) == 0:  # committed rows of the second trial
            time.sleep(0.05)
        os.kill(process.pid, signal.SIGKILL)
        process.wait(30)
        http.close()
    with serving(store) as (url, auth, _), httpx.Client(base_url=url, headers=auth, timeout=60.0) as http:
        resumed = http.get("/api/sessions/current").json()
    assert resumed["session_id"] == session and resumed["next"] == 2
    assert resumed["steps"][0]["trial_id"] == first
    assert resumed["steps"][1]["attempts"] == [{"trial_id": second, "status": "stopped", "reason": LEFT_OPEN}]

    assert main(["analyze", str(tmp_path), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "analysed 1 trials, skipped 1" in out
    report = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert f"trial {second} (participant P05" in report and "left open: no end was recorded" in report
    assert "Participants as registered" in report and "1.7" in report and "right" in report
