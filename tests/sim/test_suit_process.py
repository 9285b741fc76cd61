"""The simulated suit in its own process, driven by the real drivers over the real transports.

Every wait here is for something to happen eventually (with a deadline far beyond what any machine
needs); no verdict depends on how long something took.
"""

from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import TypeVar

import pytest

from bowden.contracts import SPEED_PEAK_DEG_S
from bowden.errors import HardwareError, ParameterError
from bowden.hardware.ads1115 import ADS1115LoadCell
from bowden.hardware.ak60 import AK60Motor
from bowden.hardware.backend import Backend
from bowden.hardware.ngimu import NgimuClient, NgimuConfig
from bowden.hardware.protocols import ElevationSample, MotorState
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.sim.backend import open_sim_backend
from bowden.sim.link.suit_process import SimulatedSuitProcess
from bowden.sim.peers.ak60_peer import ReceivedFrame
from bowden.web.reference import TrialReference

PATIENCE_S = 20.0
T = TypeVar("T")
CYCLE = MinimumJerkCycle(peak_speed_rad_s=math.radians(SPEED_PEAK_DEG_S["V1"]))


def eventually(probe: Callable[[], T | None], what: str, pause_s: float = 0.002) -> T:
    """The first value of ``probe()`` that is not None (or False), polling until ``PATIENCE_S``."""
    deadline = time.monotonic() + PATIENCE_S
    while True:
        value = probe()
        if value is not None and value is not False:
            return value
        assert time.monotonic() < deadline, f"never: {what}"
        time.sleep(pause_s)


@pytest.fixture(scope="module")
def backend() -> Iterator[Backend]:
    """One suit process for the module's device tests (starting one takes a few seconds).

    Its arm follows a reference from the loop's time 0, as in ``bowden run``: until the test calls
    ``reference_elevation`` the arm rests at the reference's low elevation.
    """
    with open_sim_backend(reference=TrialReference(cycle=CYCLE, start_s=0.0, repetitions=20)) as opened:
        yield opened


def parts(backend: Backend) -> tuple[AK60Motor, SimulatedSuitProcess]:
    assert isinstance(backend.motor, AK60Motor) and isinstance(backend.simulation, SimulatedSuitProcess)
    return backend.motor, backend.simulation


def inject(backend: Backend, target: str, method: str, *args: object) -> None:
    assert backend.inject is not None
    backend.inject(target, method, *args)


def reply(motor: AK60Motor, torque_nm: float, accept: Callable[[MotorState], bool] = lambda s: True,
          what: str = "a reply") -> MotorState:
    """Command every 2 ms until a reply that ``accept`` takes arrives."""
    def probe() -> MotorState | None:
        state = motor.command_torque(torque_nm)
        return state if state is not None and accept(state) else None

    return eventually(probe, what)


def settle(motor: AK60Motor, suit: SimulatedSuitProcess, since_s: float, commands: int) -> None:
    """Wait until the peer has handled the ``commands`` frames sent since ``since_s`` (so every reply
    is on the wire), then take the replies: nothing is left in flight."""
    eventually(lambda: len(suit.received_frames(since_s)) >= commands, "the peer handled every frame",
               pause_s=0.01)
    while motor.poll() is not None:
        pass


def fresh_sample(backend: Backend, accept: Callable[[ElevationSample], bool], what: str) -> ElevationSample:
    def probe() -> ElevationSample | None:
        sample = backend.imu.read()
        return sample if sample is not None and accept(sample) else None

    return eventually(probe, what, pause_s=0.005)


def test_the_drivers_talk_to_the_suit_and_the_arm_waits_for_the_loop(backend: Backend) -> None:
    motor, suit = parts(backend)
    assert "own process" in backend.describe and suit.pid is not None
    since = time.monotonic()
    assert motor.enable().error_code == 0
    assert reply(motor, 1.0).torque_nm > 0.0
    heard = suit.received_frames(since)
    assert heard[0].kind == "enter" and any(frame.kind == "command" for frame in heard)

    # The IMU streams, calibrated on the held arm-down pose: the arm rests at the reference's low
    # elevation as long as the loop has not started.
    for _ in range(5):
        sample = fresh_sample(backend, lambda s: True, "an IMU sample")
        assert sample.elevation_rad == pytest.approx(CYCLE.low_rad, abs=math.radians(3.0))
    assert backend.load_cell is not None
    eventually(backend.load_cell.read, "a load-cell sample")

    # The loop's first cycle ties loop time 0 to now: the arm follows the reference and rises.
    assert backend.reference_elevation is not None
    assert backend.reference_elevation(0.0) == pytest.approx(CYCLE.low_rad)
    assert suit.loop_start_notified
    fresh_sample(backend, lambda s: s.elevation_rad > CYCLE.low_rad + math.radians(15.0),
                 "the arm follows the reference once the loop runs")


def test_the_first_sample_after_the_plant_starts_is_the_running_arm_not_the_calibration_pose() -> None:
    # A slow IMU (5 Hz) leaves 200 ms between its samples: were start_plant to return before the IMU
    # sent a state of the running plant, the client's latest sample would still be the held pose (0°).
    with NgimuClient(NgimuConfig(host="127.0.0.1", port=0)) as imu:
        suit = SimulatedSuitProcess(imu_target=imu.address, cycle=CYCLE)
        suit.settings = replace(suit.settings, imu_rate_hz=5.0)
        with suit.start():
            suit.hold_arm_down()
            imu.calibrate_arm_down(1.0, min_samples=3)
            suit.hold_arm_down(False)
            suit.start_plant()
            sample = imu.read()
    assert sample is not None
    assert sample.elevation_rad == pytest.approx(CYCLE.low_rad, abs=math.radians(3.0))


def test_motor_faults(backend: Backend) -> None:
    motor, suit = parts(backend)
    motor.enable()
    inject(backend, "motor", "inject_error", 2)
    reply(motor, 0.5, lambda s: s.error_code == 2, "error code 2")
    inject(backend, "motor", "inject_error", 0)
    reply(motor, 0.5, lambda s: s.error_code == 0, "the error cleared")

    inject(backend, "motor", "override_temperature", 85.0)
    reply(motor, 0.5, lambda s: abs(s.temperature_c - 85.0) <= 1.0, "85 °C")
    inject(backend, "motor", "override_temperature", None)
    reply(motor, 0.5, lambda s: abs(s.temperature_c - 85.0) > 5.0, "the plant's temperature")

    malformed = motor.counters.malformed
    inject(backend, "motor", "replace_next_reply", bytes([1, 0, 0, 0, 0, 0, 0]).hex())  # 7 bytes
    eventually(lambda: motor.command_torque(0.5) is None and motor.counters.malformed > malformed,
               "the replaced reply refused as malformed")
    inject(backend, "motor", "garble_replies", True)
    eventually(lambda: motor.command_torque(0.5) is None and motor.counters.malformed >= malformed + 4,
               "garbled replies refused")
    inject(backend, "motor", "garble_replies", False)
    reply(motor, 0.5, what="proper replies again")

    # Three frames lost on the bus: the peer never hears them (its log says which). Leaving and
    # entering motor mode first waits for every reply: no earlier frame is still in flight.
    motor.disable()
    motor.enable()
    since = time.monotonic()
    inject(backend, "motor", "ignore_next", 3)
    torques = [0.1 * k for k in range(1, 11)]
    for torque in torques:
        motor.command_torque(torque)
    def seven_heard() -> list[ReceivedFrame] | None:
        frames = suit.received_frames(since)
        return frames if len(frames) >= 7 else None

    heard = eventually(seven_heard, "the peer handled the commands", pause_s=0.01)
    assert [frame.kind for frame in heard] == ["command"] * 7
    assert [frame.torque_nm for frame in heard] == pytest.approx(torques[3:], abs=0.02)

    # Muted: once every earlier frame is answered, nothing answers any more.
    settle(motor, suit, since, 7)
    inject(backend, "motor", "mute", True)
    assert all(motor.command_torque(0.5) is None for _ in range(20))
    assert motor.poll(0.05) is None
    inject(backend, "motor", "mute", False)
    reply(motor, 0.5, what="a reply after the mute")

    with pytest.raises(HardwareError, match="refused"):
        inject(backend, "motor", "inject_error", 999)  # not one byte: the peer refuses it
    with pytest.raises(ParameterError, match="no fault injection"):
        inject(backend, "motor", "explode")
    motor.disable()


def test_imu_faults(backend: Backend) -> None:
    inject(backend, "imu", "send_nan", True)
    fresh_sample(backend, lambda s: math.isnan(s.elevation_rad), "a NaN elevation")
    inject(backend, "imu", "send_nan", False)
    fresh_sample(backend, lambda s: math.isfinite(s.elevation_rad), "finite elevations again")

    inject(backend, "imu", "pause", True)
    latest: list[ElevationSample | None] = [backend.imu.read()]

    def quiet() -> bool:
        # Nothing new over ten reads 10 ms apart: the stream stopped.
        for _ in range(10):
            time.sleep(0.01)
            sample = backend.imu.read()
            if sample is not latest[0]:
                latest[0] = sample
                return False
        return True

    eventually(quiet, "the IMU falls silent")
    inject(backend, "imu", "pause", False)
    fresh_sample(backend, lambda s: s is not latest[0], "the IMU streams again")


def test_adc_faults_then_the_load_cell_unplugged(backend: Backend) -> None:
    cell = backend.load_cell
    assert isinstance(cell, ADS1115LoadCell)
    inject(backend, "adc", "override_tension_n", 250.0)
    eventually(lambda: (s := cell.read()) is not None and abs(s.tension_n - 250.0) < 1.0, "250 N")
    inject(backend, "adc", "override_tension_n", None)
    eventually(lambda: (s := cell.read()) is not None and s.tension_n < 200.0, "the plant's tension")

    errors = cell.counters.io_errors
    inject(backend, "adc", "fail_next", 2)  # fewer than the reader tolerates in a row
    eventually(lambda: cell.counters.io_errors >= errors + 2, "two failed reads")
    samples = cell.counters.samples
    eventually(lambda: cell.counters.samples > samples, "readings go on")
    assert cell.failure is None

    inject(backend, "i2c", "unplug")  # the device stops answering for good: every read times out
    failure = eventually(lambda: cell.failure, "the load cell declared lost", pause_s=0.01)
    assert "load cell lost" in failure


def test_closing_leaves_no_process_and_no_file_and_a_dead_child_is_one_line() -> None:
    closed, killed = (SimulatedSuitProcess(imu_target=("127.0.0.1", 9), cycle=CYCLE) for _ in range(2))
    with ThreadPoolExecutor(2) as pool:  # two interpreters importing bowden: side by side
        list(pool.map(SimulatedSuitProcess.start, (closed, killed)))
    try:
        pid, directory = closed.pid, Path(closed.can_channel).parent
        assert pid is not None and directory.is_dir() and Path(closed.i2c_path).exists()
        assert closed.start_plant() == pytest.approx(time.monotonic(), abs=PATIENCE_S)
        closed.close()
        assert not directory.exists()
        assert not Path(f"/proc/{pid}").exists()  # ended and reaped
        with pytest.raises(HardwareError, match="not running"):
            closed.hold_arm_down()

        assert killed.pid is not None
        os.kill(killed.pid, signal.SIGKILL)
        with pytest.raises(HardwareError, match="process is gone") as info:
            eventually(lambda: killed.plant_time_s() and False, "an error")
        assert "\n" not in str(info.value)
    finally:
        closed.close()
        killed.close()
    assert not Path(killed.can_channel).parent.exists()


class _ExitsOnArrival:
    """Settings that end the child as it receives them, with a message on its stderr."""

    def __reduce__(self) -> tuple[Callable[[str], object], tuple[str]]:
        return sys.exit, ("boom: the suit cannot start",)


def test_a_child_that_cannot_start_is_one_line() -> None:
    cases = {
        "could not start: AttributeError: 'object' object has no attribute 'cycle'": object(),
        r"ended before it was ready \(exit code 1\): boom: the suit cannot start": _ExitsOnArrival(),
    }
    suits = [SimulatedSuitProcess(imu_target=("127.0.0.1", 9), cycle=None, reference=reference)
             for reference in cases.values()]

    def failure(suit: SimulatedSuitProcess) -> BaseException | None:
        try:
            suit.start()
        except BaseException as error:
            return error
        suit.close()
        return None

    with ThreadPoolExecutor(2) as pool:  # two interpreters importing bowden: side by side
        errors = list(pool.map(failure, suits))
    for message, error, suit in zip(cases, errors, suits, strict=True):
        assert isinstance(error, HardwareError), error
        assert re.search(message, str(error)), str(error)
        assert "\n" not in str(error)
        assert suit.pid is None and not Path(suit.can_channel).parent.exists()


def test_settings_that_cannot_reach_the_child_are_refused() -> None:
    suit = SimulatedSuitProcess(imu_target=("127.0.0.1", 9), cycle=None, reference=lambda: None)
    with pytest.raises(ParameterError, match="must be picklable"):
        suit.start()
    assert suit.pid is None and not Path(suit.can_channel).parent.exists()


def test_the_imu_target_must_be_loopback() -> None:
    with pytest.raises(ParameterError, match="loopback"):
        SimulatedSuitProcess(imu_target=("192.168.1.10", 8000), cycle=CYCLE)


LOOP_PROCESS = """
import json, sys
from bowden.sim.backend import open_sim_backend
with open_sim_backend(speed="V1") as backend:
    suit = backend.simulation
    print(json.dumps({"suit": suit.pid, "directory": str(suit.can_channel).rsplit("/", 1)[0],
                      "imu_port": backend.imu.address[1]}), flush=True)
    sys.stdin.readline()  # the test stops us here, and kills us
"""


def udp_queue(port: int) -> tuple[int, int]:
    """(bytes waiting, datagrams dropped) on the loopback UDP socket bound to ``port``."""
    for line in Path("/proc/net/udp").read_text().splitlines()[1:]:
        fields = line.split()
        if fields[1] == f"0100007F:{port:04X}":
            return int(fields[4].split(":")[1], 16), int(fields[-1])
    raise AssertionError(f"no UDP socket on 127.0.0.1:{port}")


def process_state(pid: int) -> str | None:
    """The kernel's state letter of ``pid`` (R, S, T, Z...), None once it is gone."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(") ", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return None


def test_stopping_the_loops_process_does_not_stop_the_suit_which_ends_with_it() -> None:
    process = subprocess.Popen([sys.executable, "-c", LOOP_PROCESS], stdin=subprocess.PIPE,
                               stdout=subprocess.PIPE, text=True)
    assert process.stdin is not None and process.stdout is not None
    try:
        opened = json.loads(process.stdout.readline())
        suit, directory, port = opened["suit"], Path(opened["directory"]), opened["imu_port"]
        os.kill(process.pid, signal.SIGSTOP)
        eventually(lambda: process_state(process.pid) == "T", "the loop's process stopped")
        # While the loop's process is stopped, the simulated IMU goes on sending to its socket
        # (bytes pile up, or are dropped once its buffer is full): the devices run on.
        stopped_at = udp_queue(port)
        eventually(lambda: udp_queue(port) != stopped_at, "the IMU sends to the stopped loop",
                   pause_s=0.01)
        assert process_state(suit) not in ("T", "t", None)
        # The loop's process dies (still stopped): the suit ends by itself and leaves nothing.
        os.kill(process.pid, signal.SIGKILL)
        assert process.wait(timeout=PATIENCE_S) == -signal.SIGKILL
        eventually(lambda: process_state(suit) in (None, "Z"), "the suit's process ended", pause_s=0.01)
        eventually(lambda: not directory.exists(), "its socket files removed", pause_s=0.01)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        process.stdin.close()
        process.stdout.close()


@pytest.mark.parametrize("bench", [False, True], ids=["suit", "bench"])
def test_opening_the_simulated_suit_starts_one_process(monkeypatch, bench: bool) -> None:
    # Both backends started the suit with ``enter_context(suit.start(...))``, whose __enter__ started
    # it again: two children on one socket directory, the first removing it as it ended.
    from bowden.sim.backend import open_sim_bench

    spawned: list[int] = []
    real_popen = subprocess.Popen

    def counting_popen(args, *rest, **kwargs):
        process = real_popen(args, *rest, **kwargs)
        if "bowden.sim.link.suit_process" in args:
            spawned.append(process.pid)
        return process

    monkeypatch.setattr(subprocess, "Popen", counting_popen)
    with open_sim_bench() if bench else open_sim_backend(speed="V1") as backend:
        assert spawned == [backend.simulation.pid]
        assert Path(backend.simulation.can_channel).parent.is_dir()


def test_a_started_suit_is_not_started_twice() -> None:
    suit = SimulatedSuitProcess(imu_target=("127.0.0.1", 9), cycle=CYCLE)
    with suit.start() as entered:
        assert entered is suit
        pid = suit.pid
        with pytest.raises(RuntimeError, match="already started"):
            suit.start()
        assert suit.pid == pid
    assert suit.pid is None
