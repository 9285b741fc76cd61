"""``bowden serve --backend sim`` honours ``--motor``/``--firmware`` and ``--imu lsl:NAME`` as ``bowden run``
does, and every console trial records which actuator and IMU it ran on (issue 31).

Another motor model is driven by the real driver set up for its MIT-mode ranges, talking real frames to
that model's simulated peer; an LSL IMU is the arm published as an LSL quaternion stream and read back
by the LSL client. LSL discovery stays on this machine (``lsl_machine.cfg``). In the real-time group of
tests/conftest.py (LSL streams are seen machine-wide).
"""

from __future__ import annotations

import json
import os
import sqlite3
from pathlib import Path

import pytest

HERE = Path(__file__).parent
# liblsl reads its configuration once per process, at its first use: set it before any test runs.
os.environ["LSLAPICFG"] = str(HERE / "lsl_machine.cfg")

from starlette.testclient import TestClient  # noqa: E402

from bowden.cli import build_parser, main  # noqa: E402
from bowden.cli.serve import serve_config  # noqa: E402
from bowden.hardware.ak60 import AK60Motor  # noqa: E402
from bowden.hardware.motors import motor_limits  # noqa: E402
from bowden.model import CompensationModel  # noqa: E402
from bowden.runtime.safety import SafetyConfig  # noqa: E402
from bowden.store.schema import STORE_FILE_NAME  # noqa: E402
from bowden.web.server import ServeConfig, build_server  # noqa: E402
from bowden.web.suits import SimulatedBackend  # noqa: E402
from bowden.web.trial_setup import parse_setup  # noqa: E402

from .conftest import AUTH, BASE, SHORT_PROTOCOL, TOKEN, trial_request  # noqa: E402
from .test_app import WS, until  # noqa: E402


def _spool_after_4_nm(backend: SimulatedBackend) -> float:
    """Spool position (rad) after 4 Nm for 80 ms of simulated time (under the suit's 9 Nm peak)."""
    suit = backend.open(parse_setup(trial_request(condition="no_suit")))
    try:
        suit.motor.enable()
        state = None
        for k in range(1, 41):
            state = suit.motor.command_torque(4.0) or state
            suit.clock.sleep_until(0.002 * k)
        assert state is not None
        return state.position_rad
    finally:
        suit.close()
        assert not suit.motor.enabled


def test_another_motor_is_driven_through_its_driver_and_peer_with_its_ranges() -> None:
    backend = SimulatedBackend(motor="AK80-64", time_scale=50.0)
    suit = backend.open(parse_setup(trial_request(condition="no_suit")))
    suit.close()
    assert isinstance(suit.motor, AK60Motor)
    assert suit.motor.config.limits == motor_limits("AK80-64") and suit.motor.config.torque_limit_nm == 144.0
    assert suit.devices == {"motor_model": "AK80-64", "motor_firmware": "manual-v1.0.8", "imu": "ngimu"}
    # The peer applies what the driver packed: the spool moves as on the simulator's own motor (the
    # 12-bit ±144 Nm field rounds 4 Nm to 3.97). A peer reading the frames with the AK60-6's ±15 Nm
    # would apply 0.42 Nm, which the replies would not show (both scalings cancel), the spool would.
    reference = _spool_after_4_nm(SimulatedBackend(time_scale=50.0))
    assert _spool_after_4_nm(backend) == pytest.approx(reference, abs=0.01)


def test_serve_passes_motor_firmware_and_imu_to_the_simulated_suit(tmp_path: Path) -> None:
    args = build_parser().parse_args(["serve", "--store", str(tmp_path / "s.db"), "--motor", "AK60-6",
                                      "--firmware", "peak-9nm", "--imu", "lsl:arm"])
    backend = serve_config(args).backend
    assert isinstance(backend, SimulatedBackend)
    assert (backend.motor, backend.firmware, backend.imu) == ("AK60-6", "peak-9nm", "lsl:arm")


def test_an_lsl_imu_faster_than_it_can_stream_is_one_line(tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    store = tmp_path / "s.db"
    assert main(["serve", "--store", str(store), "--imu", "lsl:arm", "--time-scale", "20"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["bowden: error: --imu lsl:arm streams in wall time: --time-scale must be at most 5 with "
                   "it, got 20"]
    assert not store.exists()


def test_a_console_trial_on_another_motor_and_an_lsl_imu_records_both(tmp_path: Path) -> None:
    pytest.importorskip("pylsl")
    name = f"bowden-serve-arm-{os.getpid()}"
    config = ServeConfig(store_path=tmp_path / STORE_FILE_NAME, model=CompensationModel.from_friction(k=0.12),
                         backend=SimulatedBackend(time_scale=2.0, motor="AK70-10", imu=f"lsl:{name}"),
                         token=TOKEN, rate_hz=250.0, protocol=SHORT_PROTOCOL,
                         # Lenient: the IMU's LSL stream runs on a thread in wall time, which a loaded
                         # shared host can starve for tens of ms (the watchdogs are not under test).
                         safety=SafetyConfig(imu_max_age_s=0.5, motor_max_silence_s=0.5))
    web = build_server(config)
    with TestClient(web.app, base_url=BASE) as client, \
            client.websocket_connect(f"{WS}/ws/display") as display:
        display.receive_json()
        started = client.post("/api/trial/start", headers=AUTH, json=trial_request())
        assert started.status_code == 201, started.text
        stopped = until(display, "stopped")[-1]
    with sqlite3.connect(config.store_path) as connection:
        (text, reason) = connection.execute("SELECT metadata, stop_reason FROM trials WHERE id = ?",
                                            (started.json()["trial_id"],)).fetchone()
    metadata = json.loads(text)
    assert (metadata["motor_model"], metadata["motor_firmware"], metadata["imu"]) == (
        "AK70-10", "manual-v1.0.8", f"lsl:{name}")
    assert "AK70-10" in metadata["suit"] and "duration" in reason, (reason, stopped)
