"""SIGINT and SIGTERM stop ``bowden bench run`` safely: whatever the process inherited (a script's
background job ignores SIGINT, POSIX; SIGTERM's default ends the process without the safe stop), and
only at a cycle's start — never inside a device call, and never cutting the safe stop short."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from tests.runtime.bench_frames import exited

from bowden.protocol.bench import BenchProtocol
from bowden.runtime.bench import PHASE_STROKE, BenchDevices, BenchRun, BenchRunConfig, BenchSafety
from bowden.runtime.bench_recording import BenchRecordingWriter
from bowden.runtime.signals import stop_on_signals
from bowden.sim.backend import open_sim_bench


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_each_signal_asks_for_the_stop_and_the_inherited_disposition_returns(signum):
    before = signal.signal(signum, signal.SIG_IGN)  # as a background job inherits SIGINT
    asked = []
    try:
        with stop_on_signals(asked.append):
            os.kill(os.getpid(), signum)  # the handler runs before the next bytecode
        assert asked == [f"signal {signal.Signals(signum).name}"]
        assert signal.getsignal(signum) is signal.SIG_IGN
    finally:
        signal.signal(signum, before)


class SignallingMannequin:
    """The simulated mannequin's driver, sending this process a SIGTERM from inside its
    ``command_torque``: once at the first stroke's motion, once more during the safe stop."""

    def __init__(self, motor) -> None:
        self.motor = motor
        self.run: BenchRun | None = None
        self.calls_begun = self.calls_ended = 0
        self.signals_sent = 0
        self.calls_after_first = 0

    def __getattr__(self, name: str):
        return getattr(self.motor, name)

    def command_torque(self, torque_nm: float):
        self.calls_begun += 1
        if self.signals_sent == 0 and self.run is not None and self.run.phase == PHASE_STROKE:
            self._signal()
        elif self.signals_sent == 1:
            self.calls_after_first += 1
            if self.calls_after_first == 3:  # the run has stopped and ramps its torques down
                self._signal()
        state = self.motor.command_torque(torque_nm)
        self.calls_ended += 1
        return state

    def _signal(self) -> None:
        self.signals_sent += 1
        os.kill(os.getpid(), signal.SIGTERM)


def test_a_signal_inside_a_device_call_stops_at_the_next_cycle_and_a_second_one_waits_for_the_safe_stop(
        tmp_path: Path) -> None:
    # Before, the signal raised KeyboardInterrupt wherever it landed: inside the driver's call (a lock it
    # held stayed held; a bench run beside busy processes once hung at its exit), and a second one cut the
    # safe stop short, leaving both motors in motor mode.
    protocol = BenchProtocol(spool_speeds_rad_s=(1.0,), loads_nm=(1.0,), high_rad=math.radians(70.0),
                             repetitions=1)
    config = BenchRunConfig(protocol=protocol, safety=BenchSafety().on_shared_host())
    with open_sim_bench() as backend:
        mannequin = SignallingMannequin(backend.mannequin)
        devices = BenchDevices(tdu=backend.motor, mannequin=mannequin, imu=backend.imu,
                               load_cell=backend.load_cell, clock=backend.clock)
        since = backend.clock.now()
        with BenchRecordingWriter(tmp_path / "bench.csv", config.protocol_fingerprint()) as writer:
            run = mannequin.run = BenchRun(devices, config, writer)
            with stop_on_signals(run.request_stop):
                report = run.run()
        exits = set(exited(backend, since, {"motor", "mannequin"}))
    assert report.fault == "interrupted", report
    assert mannequin.signals_sent == 2
    assert mannequin.calls_begun == mannequin.calls_ended  # no device call was cut short
    assert exits == {"motor", "mannequin"}  # the safe stop went to its end


def test_a_bench_run_started_in_the_background_stops_safely_on_sigterm(tmp_path: Path) -> None:
    # Before, SIGTERM ended `bowden bench run` at once: no safe stop, no "interrupted" and exit -15.
    output = tmp_path / "bench.csv"
    command = [sys.executable, "-m", "bowden", "bench", "run", "--backend", "sim", "-o", str(output),
               "--speeds", "1", "--loads", "1", "--repetitions", "2", "--high-deg", "50"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               env={**os.environ, "PYTHONFAULTHANDLER": "1"},  # SIGABRT: the stacks
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    assert process.stderr is not None
    said = []
    for line in process.stderr:  # the first stroke recorded: the run is under way
        said.append(line)
        if line.startswith("stroke 1 of 4"):
            break
    process.send_signal(signal.SIGTERM)
    try:
        _, err = process.communicate(timeout=60)
    except subprocess.TimeoutExpired:  # say where it hangs: the stacks of all its threads
        process.send_signal(signal.SIGABRT)
        _, err = process.communicate(timeout=10)
        pytest.fail("the bench run did not end within 60 s of SIGTERM:\n" + "".join(said) + err)
    assert process.returncode == 130, "".join(said) + err
    assert "interrupted; both motors are out of motor mode" in err, err
