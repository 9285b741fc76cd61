"""Fixtures of the web tests: a server application on the simulated suit, its token, its store, and
the simulated suit behind its wire peers for the real-suit paths (``--backend can``)."""

from __future__ import annotations

import itertools
import socket
import sqlite3
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import can
import pytest
from starlette.testclient import TestClient

from bowden.model import CompensationModel
from bowden.model.model_file import save_model
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.protocol.session_plan import StudyProtocol
from bowden.sim.arm import PrescribedArm
from bowden.sim.peers import AK60Peer, NgimuPeer, WallTimePlant
from bowden.sim.peers.ak60_peer import COMMAND, EXIT, ReceivedFrame
from bowden.sim.suit import SimulatedSuit
from bowden.store.schema import STORE_FILE_NAME
from bowden.web.server import ServeConfig, WebServer, build_server
from bowden.web.suits import SimulatedBackend

TOKEN = "test-token-0123456789abcdef"
AUTH = {"X-Bowden-Token": TOKEN}
BASE = "http://127.0.0.1"
_channels = itertools.count()
ZERO_COMMAND_NM = 0.01  # a zero-torque MIT command unpacks to +3.7 mNm at ±15 Nm (12-bit field)


def virtual_channel() -> str:
    """A python-can virtual channel of this test alone."""
    return f"bowden-web-can-{next(_channels)}"


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


# A whole session kept short: the four conditions at one speed, one repetition a trial.
SHORT_PROTOCOL = StudyProtocol(speeds=("V3",), repetitions=1, lead_in_s=0.3, break_s=60.0)


def registration(participant: str = "P01", **changes: object) -> dict[str, object]:
    """A valid registration for the participant registry."""
    body: dict[str, object] = {
        "participant": participant, "height_m": 1.70, "mass_kg": 63.0, "sex": "female",
        "arm_side": "right", "hand_load_kg": 0.5, "age_years": 27,
    }
    body.update(changes)
    return body


def make_server(
    tmp_path: Path, *, time_scale: float = 20.0, rate_hz: float = 250.0,
    protocol: StudyProtocol = SHORT_PROTOCOL, token: str = TOKEN,
) -> WebServer:
    config = ServeConfig(
        store_path=tmp_path / STORE_FILE_NAME,
        model=CompensationModel.from_friction(k=0.12),
        backend=SimulatedBackend(time_scale=time_scale),
        token=token,
        rate_hz=rate_hz,
        protocol=protocol,
    )
    return build_server(config)


@pytest.fixture
def web(tmp_path: Path) -> WebServer:
    return make_server(tmp_path)


@pytest.fixture
def client(web: WebServer) -> Iterator[TestClient]:
    with TestClient(web.app, base_url=BASE) as test_client:
        yield test_client


@dataclass
class WireSuit:
    """The simulated suit behind its wire peers, and the arguments that reach it."""

    plant: WallTimePlant
    motor: AK60Peer
    imu: NgimuPeer
    channel: str
    imu_port: int
    model: Path

    def args(self) -> list[str]:
        # Lenient watchdogs: on a loaded shared machine the peers' threads, and the loop itself, can be
        # starved for tens of ms, which would (rightly) stop the suit before the test reaches the
        # behaviour it checks (a 112 ms host stall stopped the console's stop-button test once, in a
        # fresh clone's suite whose workers were compiling numba's kernels).
        return ["--backend", "can", "--interface", "virtual", "--channel", self.channel,
                "--imu-port", str(self.imu_port), "--calibration-s", "0.2", "--model", str(self.model),
                "--imu-max-age-ms", "500", "--motor-silence-ms", "500", "--host-stall-ms", "1000"]

    def frames(self) -> list[ReceivedFrame]:
        return list(self.motor.received)


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("0.0.0.0", 0))
        return int(probe.getsockname()[1])


@pytest.fixture
def wire_suit(tmp_path: Path) -> Iterator[WireSuit]:
    before = set(threading.enumerate())
    channel = virtual_channel()
    model = tmp_path / "model.json"
    save_model(CompensationModel.from_friction(k=0.12), model)
    plant = WallTimePlant(SimulatedSuit(arm=PrescribedArm.following(MinimumJerkCycle())))
    port = free_udp_port()
    with can.Bus(interface="virtual", channel=channel) as bus, AK60Peer(bus, plant) as motor, \
            NgimuPeer(plant, ("127.0.0.1", port), rate_hz=200.0) as imu:
        imu.hold_arm_down()  # the participant stands with the arm hanging for the calibration
        plant.start()
        yield WireSuit(plant, motor, imu, channel, port, model)
    # An event loop's executor threads ("asyncio_N") start lazily and live as long as their loop: in
    # the browser tests Playwright's loop starts them mid-test, and they are not the suit's.
    leaked = [
        t for t in threading.enumerate()
        if t not in before and t.is_alive() and not t.name.startswith("asyncio_")
    ]
    for thread in leaked:
        thread.join(timeout=2.0)
    running = [t.name for t in leaked if t.is_alive()]
    assert not running, f"threads left running: {running}"


def assert_safe_state_after(frames: list[ReceivedFrame], since: int) -> None:
    """From frame ``since`` on: torque commands, the last one zero, then motor mode exited, then nothing."""
    tail = frames[since:]
    kinds = [f.kind for f in tail]
    assert EXIT in kinds, "the motor never left motor mode"
    exit_at = kinds.index(EXIT)
    assert exit_at > 0 and all(f.kind == COMMAND for f in tail[:exit_at])
    assert abs(tail[exit_at - 1].torque_nm) < ZERO_COMMAND_NM, "the last command before exiting was not zero"
    assert kinds[exit_at + 1:] == [], "the motor was commanded after leaving motor mode"
