"""The simulated suit in its own process, driven by the real drivers over the real transports."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bowden.errors import HardwareError
from bowden.hardware.backend import Backend
from bowden.hardware.protocols import MotorState
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.sim.backend import open_sim_backend
from bowden.sim.link.suit_process import SimulatedSuitProcess


def wait_reply(backend: Backend, torque_nm: float, error_code: int | None = None,
               tries: int = 1000) -> MotorState:
    """Command every 2 ms until a reply (with ``error_code``, if given) arrives."""
    for _ in range(tries):
        state = backend.motor.command_torque(torque_nm)
        if state is not None and (error_code is None or state.error_code == error_code):
            return state
        time.sleep(0.002)
    raise AssertionError("no such reply")


def test_the_drivers_run_the_suit_and_faults_reach_its_devices() -> None:
    with open_sim_backend(speed="V1") as backend:
        assert "own process" in backend.describe and backend.inject is not None
        state = backend.motor.enable()
        assert state.error_code == 0
        assert wait_reply(backend, 1.0).torque_nm > 0.0
        deadline = time.monotonic() + 5.0
        while (sample := backend.imu.read()) is None and time.monotonic() < deadline:
            time.sleep(0.005)
        assert sample is not None and 0.0 <= sample.elevation_rad < 2.0
        assert backend.load_cell is not None
        deadline = time.monotonic() + 5.0
        while backend.load_cell.read() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert backend.load_cell.read() is not None

        backend.inject("motor", "inject_error", 2)
        wait_reply(backend, 0.5, error_code=2)
        backend.inject("motor", "inject_error", 0)
        backend.inject("motor", "mute", True)
        time.sleep(0.05)
        while backend.motor.command_torque(0.5) is not None:  # replies already on their way
            time.sleep(0.002)
        assert all(backend.motor.command_torque(0.5) is None for _ in range(10))
        backend.inject("motor", "mute", False)
        wait_reply(backend, 0.5, error_code=0)

        backend.inject("adc", "override_tension_n", 250.0)
        deadline = time.monotonic() + 5.0
        while (reading := backend.load_cell.read()) is not None and reading.tension_n < 200.0:
            assert time.monotonic() < deadline
            time.sleep(0.01)
        backend.inject("imu", "pause", True)
        time.sleep(0.05)
        backend.imu.read()
        before = backend.imu.read()
        time.sleep(0.1)
        assert backend.imu.read() is before  # nothing new while the IMU is silent
        with pytest.raises(HardwareError, match="refused"):
            backend.inject("motor", "inject_error", 999)  # not one byte: the peer refuses it
        backend.motor.disable()


def test_closing_leaves_no_process_and_no_file() -> None:
    suit = SimulatedSuitProcess(imu_target=("127.0.0.1", 9), cycle=MinimumJerkCycle()).start()
    pid, directory = suit.pid, Path(suit.can_channel).parent
    assert pid is not None and directory.is_dir() and Path(suit.i2c_path).exists()
    suit.close()
    assert not directory.exists()
    assert not Path(f"/proc/{pid}").exists()  # ended and reaped


def test_a_child_that_cannot_start_is_one_line() -> None:
    suit = SimulatedSuitProcess(imu_target=("127.0.0.1", 9), cycle=None, reference=object())
    with pytest.raises(HardwareError, match="could not start"):
        suit.start()


PAUSED_PARENT = """
import json, sys, time
from bowden.sim.backend import open_sim_backend
with open_sim_backend(speed="V1") as backend:
    pid = int(backend.describe.split("pid ")[1].split(")")[0])
    backend.imu.read()
    print(json.dumps({"suit": pid}), flush=True)
    sys.stdin.readline()  # the test stops us here, then lets us go on
    print(json.dumps({"datagrams": backend.imu.poll()}), flush=True)
"""


def test_stopping_the_loops_process_does_not_stop_the_devices() -> None:
    process = subprocess.Popen([sys.executable, "-c", PAUSED_PARENT], stdin=subprocess.PIPE,
                               stdout=subprocess.PIPE, text=True)
    assert process.stdin is not None and process.stdout is not None
    try:
        suit = json.loads(process.stdout.readline())["suit"]
        os.kill(process.pid, signal.SIGSTOP)
        time.sleep(0.3)
        state = Path(f"/proc/{suit}/stat").read_text().split(") ")[1].split()[0]
        os.kill(process.pid, signal.SIGCONT)
        assert state != "T"  # the suit's process ran on while the loop's was stopped
        process.stdin.write("\n")
        process.stdin.flush()
        taken = json.loads(process.stdout.readline())["datagrams"]
        assert taken > 0  # the IMU kept streaming; the datagrams waited on the socket
    finally:
        process.stdin.close()
        assert process.wait(timeout=60) == 0
