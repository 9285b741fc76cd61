"""The trigger line of `bowden serve --trigger` when a console trial's loop fails mid-trial: the line
still goes low, the trial's sync events are recorded and its recording closed (nothing left high)."""

from __future__ import annotations

import sqlite3
import sys
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path

from starlette.testclient import TestClient

from bowden.cli import build_parser
from bowden.cli.serve import serve_config, synced
from bowden.runtime.sync_events import SYNC_KIND
from bowden.web.server import build_server
from bowden.web.suits import OpenSuit, SimulatedBackend
from bowden.web.trial_setup import TrialSetup

from .conftest import AUTH, BASE, TOKEN, trial_request

TRIGGER_LOG = Path(__file__).parents[1] / "runtime" / "trigger_log.py"
FAIL_AFTER = 150  # torque commands before the motor's driver breaks


class BreakingMotor:
    """The simulated suit's motor, whose driver raises a bug (not a device error) after a while."""

    def __init__(self, motor: object) -> None:
        self._motor = motor
        self.commands = 0

    def command_torque(self, torque_nm: float) -> object:
        self.commands += 1
        if self.commands > FAIL_AFTER:
            raise ZeroDivisionError("a bug in the motor driver")
        return self._motor.command_torque(torque_nm)  # type: ignore[attr-defined]

    def __getattr__(self, name: str) -> object:
        return getattr(self._motor, name)


class BreakingBackend(SimulatedBackend):
    def open(self, setup: TrialSetup) -> OpenSuit:
        suit = super().open(setup)
        return replace(suit, motor=BreakingMotor(suit.motor))  # type: ignore[arg-type]


def test_a_loop_that_fails_mid_trial_still_lowers_the_line_and_records_its_edges(tmp_path: Path) -> None:
    levels = tmp_path / "levels.txt"
    store = tmp_path / "study.db"
    trigger = f"command:{sys.executable} {TRIGGER_LOG} {levels} {{level}}"
    args = build_parser().parse_args(["serve", "--store", str(store), "--port", "0", "--rate-hz", "250",
                                      "--trigger", trigger])
    with ExitStack() as stack:
        config = replace(synced(serve_config(args), args, stack), backend=BreakingBackend(time_scale=5.0),
                         token=TOKEN)
        web = build_server(config)
        with TestClient(web.app, base_url=BASE) as client, \
                client.websocket_connect("ws://127.0.0.1/ws/console") as console:
            console.send_json({"token": TOKEN})
            started = client.post("/api/trial/start", headers=AUTH, json=trial_request())
            assert started.status_code == 201, started.text
            while (result := console.receive_json())["type"] != "stopped":
                pass
    assert result["error"] == "ZeroDivisionError: a bug in the motor driver" and not result["clean"]
    assert [line.split()[0] for line in levels.read_text().splitlines()] == ["1", "0"]
    assert result["sync"][0].startswith("sync: trigger edges sent: start within ")
    with sqlite3.connect(store) as connection:
        ended, reason = connection.execute("SELECT ended_utc, stop_reason FROM trials").fetchone()
        edges = connection.execute("SELECT message FROM events WHERE kind = ?", (SYNC_KIND,)).fetchall()
    assert ended is not None and reason.startswith("error: ZeroDivisionError")
    assert len(edges) == 2
