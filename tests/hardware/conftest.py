"""Fixtures for the wire-level tests: a small plant behind the peers, virtual CAN buses, leak checks.

The plant is deliberately simple (a first-order torque lag on a spool with inertia and viscous
friction, an arm moving along a prescribed minimum-jerk cycle): the tests here are about the bytes on
the wire, not the physics, which the simulation issue owns.
"""

from __future__ import annotations

import itertools
import math
import threading
from collections.abc import Iterator
from types import TracebackType
from typing import Self

import can
import pytest

from bowden.hardware.protocols import ElevationSample, MotorState, TensionSample
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.sim.peers import WallTimePlant


class FirstOrderMotor:
    """Torque source with a first-order lag driving a spool (J, viscous b), integrated by the plant."""

    def __init__(self, *, lag_s: float = 0.001, inertia_kg_m2: float = 1.5e-3, damping_nm_s: float = 0.05):
        self.lag_s = lag_s
        self.inertia_kg_m2 = inertia_kg_m2
        self.damping_nm_s = damping_nm_s
        self.time_s = 0.0
        self.position_rad = 0.0
        self.velocity_rad_s = 0.0
        self.torque_nm = 0.0
        self.command_nm = 0.0
        self.temperature_c = 30.0
        self.enabled = False

    def integrate(self, dt: float) -> None:
        alpha = 1.0 - math.exp(-dt / self.lag_s)
        self.torque_nm += alpha * (self.command_nm - self.torque_nm)
        acceleration = (self.torque_nm - self.damping_nm_s * self.velocity_rad_s) / self.inertia_kg_m2
        self.velocity_rad_s += acceleration * dt
        self.position_rad += self.velocity_rad_s * dt
        self.time_s += dt

    def _state(self) -> MotorState:
        return MotorState(self.time_s, self.position_rad, self.velocity_rad_s, self.torque_nm,
                          self.temperature_c, 0)

    def enable(self) -> MotorState:
        self.enabled = True
        return self._state()

    def disable(self) -> None:
        self.enabled = False
        self.command_nm = 0.0

    def set_zero(self) -> None:
        self.position_rad = 0.0

    def command_torque(self, torque_nm: float) -> MotorState:
        self.command_nm = torque_nm if self.enabled else 0.0
        return self._state()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.disable()


class PrescribedArm:
    """Elevation along a minimum-jerk cycle starting at ``start_s`` (arm hanging before it)."""

    def __init__(self, plant: SimplePlant, cycle: MinimumJerkCycle) -> None:
        self._plant = plant
        self.cycle = cycle

    def read(self) -> ElevationSample:
        t = self._plant.time_s
        cycle = self.cycle
        return ElevationSample(t, float(cycle.elevation_rad(t)), float(cycle.elevation_velocity_rad_s(t)))

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        return None


class CableTension:
    """Tension at the anchor: motor torque over a 35 mm spool, never negative (a cable cannot push)."""

    def __init__(self, plant: SimplePlant, *, pulley_radius_m: float = 0.035) -> None:
        self._plant = plant
        self.pulley_radius_m = pulley_radius_m

    def read(self) -> TensionSample:
        return TensionSample(self._plant.time_s, max(0.0, self._plant.motor.torque_nm) / self.pulley_radius_m)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        return None


class SimplePlant:
    """Implements ``bowden.sim.peers.Plant`` for the wire tests."""

    def __init__(self, cycle: MinimumJerkCycle | None = None, *, step_s: float = 2e-4) -> None:
        self.time_s = 0.0
        self.step_s = step_s
        self.motor = FirstOrderMotor()
        self.elevation_sensor = PrescribedArm(self, cycle if cycle is not None else MinimumJerkCycle())
        self.tension_sensor = CableTension(self)

    def advance_to(self, time_s: float) -> None:
        while self.time_s < time_s:
            dt = min(self.step_s, time_s - self.time_s)
            self.motor.integrate(dt)
            self.time_s += dt


_channels = itertools.count()


@pytest.fixture
def can_channel() -> str:
    """A virtual CAN channel name no other test uses."""
    return f"bowden-test-{next(_channels)}"


@pytest.fixture
def can_buses(can_channel: str) -> Iterator[tuple[can.BusABC, can.BusABC]]:
    """(driver bus, peer bus) on one virtual channel, shut down afterwards."""
    driver_bus = can.Bus(interface="virtual", channel=can_channel)
    peer_bus = can.Bus(interface="virtual", channel=can_channel)
    try:
        yield driver_bus, peer_bus
    finally:
        driver_bus.shutdown()
        peer_bus.shutdown()


@pytest.fixture
def plant() -> SimplePlant:
    return SimplePlant()


@pytest.fixture
def wall_plant(plant: SimplePlant) -> WallTimePlant:
    shared = WallTimePlant(plant)
    shared.start()
    return shared


@pytest.fixture(autouse=True)
def no_leaked_threads() -> Iterator[None]:
    """Fail a test that leaves a thread running (peers, servers, readers must all be closed)."""
    before = set(threading.enumerate())
    yield
    leaked = [t for t in threading.enumerate() if t not in before and t.is_alive()]
    for thread in leaked:
        thread.join(timeout=1.0)
    leaked = [t for t in leaked if t.is_alive()]
    assert not leaked, f"threads left running: {[t.name for t in leaked]}"
