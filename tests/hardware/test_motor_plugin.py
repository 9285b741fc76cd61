"""The worked plug-in example of docs/hardware.md (docs/examples/servo_motor.py): a motor class and
its simulated peer, on python-can's virtual bus, driven by the controller's own loop.

Its peer answers on a thread, so the loop test is in the real-time group of tests/conftest.py.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType, TracebackType
from typing import Any, Self

import can
import pytest
from tests.module_from_path import load_module

from bowden.control import build_controller
from bowden.hardware.protocols import ElevationSample, Motor
from bowden.model import CompensationModel, Subject
from bowden.runtime import ControlLoop, LoopConfig, MonotonicClock

EXAMPLE = Path(__file__).parents[2] / "docs" / "examples" / "servo_motor.py"
# AK80-9: 0.091 Nm/A on the motor side × 9 (CubeMars, via TMotorCANControl): 0.819 Nm/A at the output.
NM_PER_A = 0.091 * 9.0


def load_example() -> ModuleType:
    return load_module("servo_motor_example", EXAMPLE)


example = load_example()


@pytest.fixture
def pair(can_buses: tuple[can.BusABC, can.BusABC]) -> Iterator[tuple[Any, Any]]:
    with example.ServoCurrentPeer(can_buses[1]) as peer:
        yield example.ServoCurrentMotor(can_buses[0]), peer


def test_the_example_implements_the_motor_protocol(pair: tuple[Any, Any]) -> None:
    motor, _ = pair
    assert isinstance(motor, Motor)


def test_a_torque_goes_out_as_the_current_of_the_torque_constant(pair: tuple[Any, Any]) -> None:
    motor, peer = pair
    first = motor.enable()
    assert first.temperature_c == 30.0 and first.error_code == 0
    motor.command_torque(2.0)
    deadline = time.monotonic() + 5.0
    while peer.applied_current_a == 0.0 and time.monotonic() < deadline:
        time.sleep(0.005)
    assert peer.applied_current_a == pytest.approx(2.0 / NM_PER_A, abs=0.001)  # 2.442 A, in mA steps
    state = None
    while state is None and time.monotonic() < deadline:
        state = motor.command_torque(2.0)
        time.sleep(0.005)
    assert state is not None and state.torque_nm == pytest.approx(2.0, abs=0.01 * NM_PER_A)
    motor.disable()
    time.sleep(0.1)
    assert peer.applied_current_a == 0.0


class StillArm:
    """An IMU reading a still arm at 40°, stamped on the loop's clock."""

    def __init__(self, clock: MonotonicClock) -> None:
        self.clock = clock

    def read(self) -> ElevationSample:
        return ElevationSample(self.clock.now(), math.radians(40.0), 0.0)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        pass


def test_the_loop_drives_the_plugged_in_motor_and_leaves_it_limp(pair: tuple[Any, Any]) -> None:
    motor, peer = pair
    clock = MonotonicClock()
    controller = build_controller(model=CompensationModel.from_friction(k=0.1), support=0.5,
                                  subject=Subject(height_m=1.70, mass_kg=63.0, sex="female"))
    currents: list[float] = []
    loop = ControlLoop(controller=controller, motor=motor, elevation_sensor=StillArm(clock), clock=clock,
                       config=LoopConfig(rate_hz=200.0, duration_s=0.5),
                       record=lambda row: currents.append(peer.applied_current_a))
    report = loop.run()
    assert report.clean, report.reason
    assert max(currents) > 0.1  # the controller's torque reached the motor as current
    time.sleep(0.1)
    assert peer.applied_current_a == 0.0  # the loop left it limp
