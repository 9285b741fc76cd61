"""``bowden run`` end to end on the simulated suit (real drivers, wire peers), and its errors."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from bowden.cli import main
from bowden.contracts import TRIAL_COLUMNS
from bowden.model import CompensationModel


def test_run_sim_records_a_trial(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    store = tmp_path / "study.db"
    model = tmp_path / "model.json"
    CompensationModel.from_friction(k=0.12).save(model)
    code = main(["run", "--backend", "sim", "--model", str(model), "--support", "0.25", "--duration", "0.6",
                 "--rate", "250", "--record", str(store), "--participant", "P03", "--speed", "V2"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "stopped: duration 0.6 s reached" in out
    assert "motor mode exited" in out and "deadline misses" in out
    with sqlite3.connect(store) as connection:
        trial = connection.execute(
            "SELECT participant, condition, speed, support, stop_reason, ended_utc FROM trials"
        ).fetchone()
        assert trial[:5] == ("P03", "support_25", "V2", 0.25, "duration 0.6 s reached")
        assert trial[5] is not None
        query = f"SELECT {', '.join(TRIAL_COLUMNS)} FROM samples ORDER BY time_s"
        rows = connection.execute(query).fetchall()
        events = connection.execute("SELECT kind, message FROM events").fetchall()
    assert len(rows) >= 100  # 0.6 s at 250 Hz, less any cycles a busy machine made the loop skip
    columns = dict(zip(TRIAL_COLUMNS, zip(*rows, strict=True), strict=True))
    assert all(value is not None for value in columns["elevation_rad"])
    assert all(value is not None for value in columns["reference_elevation_rad"])
    assert max(columns["commanded_torque_nm"]) > 0.0
    assert any(value is not None for value in columns["tension_n"])  # the load cell was recorded
    assert events == [("safe_stop", "NONE: duration 0.6 s reached")]


def test_can_backend_needs_a_model(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--backend", "can"]) == 1
    assert "needs --model" in capsys.readouterr().err


@pytest.mark.parametrize(("argument", "message"), [
    (["--support", "half"], "--support must be"),
    (["--support", "0.3", "--record", "x.db"], "no study condition for support 0.3"),
    (["--rate", "9000"], "rate_hz"),
])
def test_bad_arguments_fail_before_touching_devices(argument: list[str], message: str,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--backend", "sim", *argument]) == 1
    assert message in capsys.readouterr().err


def test_cli_imu_port_default_is_the_ngimu_default() -> None:
    from bowden.cli.run import DEFAULT_IMU_PORT
    from bowden.hardware.ngimu import DEFAULT_HOST_PORT

    assert DEFAULT_IMU_PORT == DEFAULT_HOST_PORT == 8000
