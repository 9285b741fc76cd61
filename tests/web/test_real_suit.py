"""The real-suit paths of the browser, on the wire: ``bowden serve --backend can`` and ``bowden run --serve``.

No hardware here, so the suit is the simulated one behind peers that speak the real protocols: an
AK60-6 peer on python-can's virtual bus (``--interface virtual``) and an NGIMU peer sending OSC
bundles over real UDP to ``--imu-port``. The commands are built from their real arguments, the
server listens on a real socket, and the tests talk to it as a browser does (HTTP with the session
token, WebSockets). What reaches the motor is read from the peer's log of the frames it heard.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import io
import itertools
import json
import math
import re
import sqlite3
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import httpx2 as httpx  # what the dev extra installs (starlette's TestClient uses it too)
from websockets.sync.client import ClientConnection, connect

from bowden.cli import build_parser, main
from bowden.cli.serve import serve_config
from bowden.control import Fault
from bowden.model import CompensationModel
from bowden.model.model_file import save_model
from bowden.runtime import LoopState
from bowden.sim.peers.ak60_peer import COMMAND, ENTER, EXIT
from bowden.store.sample_chunks import read_samples
from bowden.web.server import ServerThread

from .conftest import (
    WireSuit,
    assert_safe_state_after,
    free_udp_port,
    store_snapshot,
    trial_request,
    virtual_channel,
)


@contextlib.contextmanager
def console_socket(url: str, token: str) -> Iterator[ClientConnection]:
    """The console's live socket, authorised by its first message as the console page does."""
    with connect(url.replace("http://", "ws://") + "/ws/console", open_timeout=5.0) as ws:
        ws.send(json.dumps({"token": token}))
        yield ws


def until(ws: ClientConnection, kind: str, *, timeout_s: float = 20.0) -> list[dict[str, object]]:
    """Messages from a socket up to and including the first of type ``kind``."""
    seen = []
    deadline = time.monotonic() + timeout_s
    while True:
        message = json.loads(ws.recv(timeout=max(0.1, deadline - time.monotonic())))
        seen.append(message)
        if message["type"] == kind:
            return seen


def samples_until(ws: ClientConnection, predicate, *, timeout_s: float = 20.0) -> list[dict[str, object]]:
    """Sample messages until one satisfies ``predicate`` (the trial must not stop meanwhile)."""
    seen = []
    deadline = time.monotonic() + timeout_s
    while True:
        message = json.loads(ws.recv(timeout=max(0.1, deadline - time.monotonic())))
        assert message["type"] != "stopped", f"the trial stopped: {message}"
        if message["type"] == "samples":
            seen.append(message)
            if predicate(message):
                return seen


def assert_ramped_down(rows: list[tuple[object, ...]]) -> None:
    """The recorded end of a trial: the torque ramps monotonically to exactly zero."""
    ramp = [float(r[3]) for r in rows if r[4] == LoopState.RAMPING_DOWN]
    assert len(ramp) >= 2 and ramp[-1] == 0.0
    assert all(b <= a for a, b in itertools.pairwise(ramp)), "the torque did not ramp down"
    assert all(r[4] == LoopState.RUNNING for r in rows[: len(rows) - len(ramp)])


def wait_until_assisting(suit: WireSuit, timeout_s: float = 10.0) -> None:
    """Wait until the loop has entered motor mode and commands torque (it starts after the request)."""
    deadline = time.monotonic() + timeout_s
    while not (suit.motor.in_motor_mode and suit.frames()[-1].kind == COMMAND):
        assert time.monotonic() < deadline, "the loop never started commanding the motor"
        time.sleep(0.01)


def stored(path: Path, trial_id: int) -> tuple[tuple[object, ...], list[tuple[object, ...]], list[tuple]]:
    with sqlite3.connect(path) as connection:
        trial = connection.execute(
            "SELECT participant, condition, speed, support, stop_reason, ended_utc FROM trials WHERE id = ?",
            (trial_id,),
        ).fetchone()
        columns = ["time_s", "reference_elevation_rad", "elevation_rad", "commanded_torque_nm",
                   "controller_state", "fault_flags"]
        samples = list(read_samples(connection, trial_id).loc[:, columns].itertuples(index=False, name=None))
        events = connection.execute(
            "SELECT kind, message FROM events WHERE trial_id = ?", (trial_id,)
        ).fetchall()
    return trial, samples, events


def test_serve_backend_can_runs_console_trials_on_the_wire(wire_suit: WireSuit, tmp_path: Path) -> None:
    store = tmp_path / "study.sqlite"
    args = build_parser().parse_args(["serve", *wire_suit.args(), "--store", str(store), "--port", "0",
                                      "--rate-hz", "250"])
    with ServerThread(serve_config(args)) as server, httpx.Client(base_url=server.url, timeout=10.0) as http:
        token = server.web.token.value
        auth = {"X-Bowden-Token": token}
        assert http.get("/api/options").json()["backend"] == "can"
        with console_socket(server.url, token) as console:
            until(console, "trial")  # the console's first message: the server's state
            started = http.post("/api/trial/start", headers=auth, json=trial_request(repetitions=10))
            assert started.status_code == 201, started.text
            trial_id = started.json()["trial_id"]
            assert started.json()["suit"].startswith("AK60-6 id 1 on virtual:")
            wire_suit.imu.hold_arm_down(False)  # calibrated: the arm follows its cycle
            # Live samples of the real loop reach the console: the measured arm, the motor torque.
            samples = samples_until(console, lambda m: max(m["elevation_deg"]) > 30.0)
            assert any(t > 0.0 for m in samples for t in m["commanded_torque_nm"])
            assert wire_suit.motor.in_motor_mode

            # A stop without the token is refused and changes nothing: the loop keeps assisting.
            frames_before = len(wire_suit.frames())
            refused = http.post("/api/trial/stop", json={})
            assert refused.status_code == 403
            wrong = {"X-Bowden-Token": "x" * 43}
            assert http.post("/api/trial/stop", headers=wrong, json={}).status_code == 403
            samples_until(console, lambda m: True)
            health = http.get("/api/console/status", headers=auth).json()["health"]
            assert health["state"] == "running" and health["stop_requested"] is None
            assert wire_suit.motor.in_motor_mode
            assert EXIT not in [f.kind for f in wire_suit.frames()[frames_before:]]

            # The console's stop: the runtime's safe state on the wire.
            since = len(wire_suit.frames())
            assert http.post("/api/trial/stop", headers=auth, json={}).status_code == 200
            result = until(console, "stopped")[-1]
        assert result["clean"] is True and result["motor_disabled"] is True
        assert result["reason"] == "operator stop (console)"
        assert not wire_suit.motor.in_motor_mode
        assert_safe_state_after(wire_suit.frames(), since)

        # The suit was closed after the trial and opens again (with its calibration) for the next.
        wire_suit.imu.hold_arm_down()
        second = http.post("/api/trial/start", headers=auth, json=trial_request(participant="P02"))
        assert second.status_code == 201, second.text
        wire_suit.imu.hold_arm_down(False)
        wait_until_assisting(wire_suit)
        since_second = len(wire_suit.frames())
    # Shutting the server down (Ctrl-C) stopped the running trial safely first.
    assert not wire_suit.motor.in_motor_mode
    assert_safe_state_after(wire_suit.frames(), since_second)

    trial, rows, events = stored(store, trial_id)
    assert trial[:5] == ("P01", "support_50", "V3", 0.5, "operator stop (console)") and trial[5] is not None
    # Each trial takes up the slack first (a `slack` event, unless the stop came before it was done).
    assert run_events(events[:-1]) in ([], ["slack"]), events
    assert events[-1] == ("safe_stop", "operator stop (console)")
    assert len(rows) == result["cycles"] == result["committed_rows"]  # every cycle is in the store
    assert_ramped_down(rows)
    assert rows[-1][5] & int(Fault.STOP_REQUESTED)
    assert max(math.degrees(r[2]) for r in rows) > 30.0  # the IMU's elevation, over UDP
    assert not any(math.isnan(r[1]) for r in rows)  # the reference shown is recorded
    second_trial, _, _ = stored(store, trial_id + 1)
    assert second_trial[0] == "P02" and second_trial[4] == "server shutting down"


def run_events(events: list[tuple[object, ...]]) -> list[object]:
    """The kinds of the trial's events but the host's: a busy machine may not schedule the loop for a
    while, which the loop records (``host_stall``) and tolerates up to ``--host-stall-ms``."""
    return [kind for kind, _ in events if kind != "host_stall"]


class Lines(io.TextIOBase):
    """A thread-safe stdout that keeps every line, for reading what a command printed while it runs."""

    def __init__(self) -> None:
        self._text = ""
        self._changed = threading.Condition()

    def write(self, text: str) -> int:
        with self._changed:
            self._text += text
            self._changed.notify_all()
        return len(text)

    def wait_for(self, pattern: str, timeout_s: float = 20.0) -> re.Match[str]:
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while (match := re.search(pattern, self._text)) is None:
                if not self._changed.wait(max(0.0, deadline - time.monotonic())):
                    raise AssertionError(f"never printed {pattern!r}; printed:\n{self._text}")
            return match

    @property
    def text(self) -> str:
        return self._text


def test_run_serve_shows_the_run_and_the_console_stops_it(wire_suit: WireSuit, tmp_path: Path) -> None:
    store = tmp_path / "study.sqlite"
    # The suit's peers are threads of this test process: a busy machine stalls them with the loop, so
    # the host-stall bound is set out of the way (its own tests are in tests/runtime).
    argv = ["run", *wire_suit.args(), "--serve", "--port", "0", "--record", str(store), "--rate", "250",
            "--duration", "60", "--participant", "P07", "--speed", "V2", "--lead-in", "0.5",
            "--host-stall-ms", "2000"]
    out = Lines()
    with contextlib.redirect_stdout(out), concurrent.futures.ThreadPoolExecutor(1) as pool:
        running = pool.submit(main, argv)
        url = out.wait_for(r"bowden run --serve: (http://\S+)").group(1)
        token = out.wait_for(r"session token:\s+(\S+)").group(1)
        with httpx.Client(base_url=url, timeout=10.0) as http, \
                connect(url.replace("http://", "ws://") + "/ws/display", open_timeout=5.0) as display, \
                console_socket(url, token) as console:
            # The display is told of the run's trial when its loop starts (after the calibration).
            trial = until(display, "trial")[-1]
            if trial["state"] != "running":
                trial = until(display, "trial")[-1]
            assert trial["state"] == "running" and "setup" not in trial  # no participant id on the display
            assert trial["reference"]["repetitions"] >= 1 and trial["reference"]["start_s"] == 0.5
            wire_suit.imu.hold_arm_down(False)
            seen = samples_until(display, lambda m: max(m["elevation_deg"]) > 30.0)
            assert all(r is not None for m in seen for r in m["reference_deg"])

            # Starting another trial from the console is refused: this server shows the run.
            auth = {"X-Bowden-Token": token}
            assert http.post("/api/trial/start", headers=auth, json=trial_request()).status_code == 409
            # A stop without the token is refused and changes nothing.
            frames_before = len(wire_suit.frames())
            assert http.post("/api/trial/stop", json={}).status_code == 403
            samples_until(display, lambda m: True)
            assert not running.done() and wire_suit.motor.in_motor_mode
            assert EXIT not in [f.kind for f in wire_suit.frames()[frames_before:]]

            since = len(wire_suit.frames())
            assert http.post("/api/trial/stop", headers=auth, json={}).status_code == 200
            result = until(console, "stopped")[-1]
            assert result["clean"] is True and result["reason"] == "operator stop (console)"
            code = running.result(timeout=20.0)
    assert code == 0, out.text
    assert "stopped: operator stop (console) (STOP_REQUESTED)" in out.text
    assert "motor mode exited" in out.text
    assert not wire_suit.motor.in_motor_mode
    assert_safe_state_after(wire_suit.frames(), since)
    assert [f.kind for f in wire_suit.frames()].count(ENTER) == 1

    trial_row, rows, events = stored(store, result["trial_id"])
    assert len(rows) == result["cycles"] == result["committed_rows"]
    assert trial_row[:5] == ("P07", "support_50", "V2", 0.5, "operator stop (console)")
    # The real suit starts each trial by taking up the slack (a `slack` event once it is done).
    assert run_events(events[:-1]) in ([], ["slack"]), events
    assert events[-1] == ("safe_stop", "STOP_REQUESTED: operator stop (console)")
    assert_ramped_down(rows)
    assert not any(math.isnan(r[1]) for r in rows)  # the reference the display showed
    assert max(math.degrees(r[2]) for r in rows) > 30.0


def test_a_real_suit_that_cannot_be_opened_refuses_the_start_and_leaves_nothing_open(
    tmp_path: Path,
) -> None:
    model = tmp_path / "model.json"
    save_model(CompensationModel.from_friction(k=0.12), model)
    store = tmp_path / "study.sqlite"
    port = free_udp_port()
    common = ["serve", "--backend", "can", "--model", str(model), "--store", str(store), "--port", "0",
              "--imu-port", str(port), "--calibration-s", "0.1"]
    unplugged = build_parser().parse_args([*common, "--interface", "no-such-interface", "--channel", "can5"])
    silent_imu = build_parser().parse_args([*common, "--interface", "virtual",
                                            "--channel", virtual_channel()])
    for args, message in ((unplugged, "cannot open the CAN interface no-such-interface:can5"),
                          (silent_imu, f"is the IMU sending /quaternion to port {port}?")):
        with ServerThread(serve_config(args)) as server, httpx.Client(base_url=server.url) as http:
            auth = {"X-Bowden-Token": server.web.token.value}
            before = store_snapshot(store)
            for _ in range(2):  # the second attempt finds the UDP port and the bus free again
                refused = http.post("/api/trial/start", headers=auth, json=trial_request(), timeout=10.0)
                assert refused.status_code == 503 and message in refused.json()["error"]
            assert not server.web.manager.running and store_snapshot(store) == before
