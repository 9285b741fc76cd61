"""``bowden run --backend sim --motor AK70-10 --imu lsl:NAME`` runs a trial (issue 31, "Done when").

The simulated suit, in its own process, has an AK70-10 speaking its own MIT ranges and an IMU that
publishes the arm as an LSL quaternion stream; the loop's process reads it with the LSL client.
Discovery stays on this machine (ResolveScope = machine). In the real-time group of tests/conftest.py.
"""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pylsl")


def test_a_trial_with_another_motor_and_an_lsl_imu(tmp_path: Path) -> None:
    config = tmp_path / "lsl_api.cfg"
    config.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n")
    name = f"bowden-test-arm-{os.getpid()}"
    run = subprocess.run(
        [sys.executable, "-m", "bowden", "run", "--backend", "sim", "--motor", "AK70-10",
         "--imu", f"lsl:{name}", "--duration", "1", "--rate", "250", "--lead-in", "0.5",
         "--record", "study.db"],
        env={**os.environ, "LSLAPICFG": str(config)}, cwd=tmp_path, capture_output=True, text=True,
        timeout=240,
    )
    assert run.returncode == 0, run.stderr
    assert "AK70-10 (50 rad/s, 25 Nm ranges)" in run.stderr
    assert f"LSL quaternion stream '{name}'" in run.stderr
    assert "stopped: duration 1 s reached (no fault)" in run.stdout + run.stderr
    with sqlite3.connect(tmp_path / "study.db") as connection:  # the store says what the trial ran on
        (text,) = connection.execute("SELECT metadata FROM trials").fetchone()
    metadata = json.loads(text)
    assert (metadata["motor_model"], metadata["motor_firmware"], metadata["imu"]) == (
        "AK70-10", "manual-v1.0.8", f"lsl:{name}")
