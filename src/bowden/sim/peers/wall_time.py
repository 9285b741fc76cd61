"""A simulated plant shared by several peers and advanced in wall time.

The peers run in their own threads (the CAN motor answering frames, the IMU streaming bundles, the
ADC converting) and each needs the plant "now". :class:`WallTimePlant` serialises their access with
one lock and, before every access, integrates the plant up to the current wall time, so the physics
runs at real speed whoever asks first. Before :meth:`WallTimePlant.start` the plant is frozen at its
initial time: devices answer, but nothing moves (time for the arm-down calibration, say).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Protocol, TypeVar

from bowden.errors import HardwareError
from bowden.hardware.protocols import (
    ElevationSample,
    ElevationSensor,
    Motor,
    MotorState,
    TensionSample,
    TensionSensor,
)

_T = TypeVar("_T")


class Plant(Protocol):
    """What a peer needs from a simulated suit (``bowden.sim.SimulatedSuit`` implements it).

    ``advance_to`` integrates the physics to an absolute plant time (s, from 0); the devices read and
    command the plant at its current time.
    """

    @property
    def motor(self) -> Motor: ...

    @property
    def elevation_sensor(self) -> ElevationSensor: ...

    @property
    def tension_sensor(self) -> TensionSensor: ...

    def advance_to(self, time_s: float) -> None: ...


class WallTimePlant:
    """Thread-safe access to a :class:`Plant` integrated to wall time.

    Parameters
    ----------
    plant
        The simulated suit.
    time_source
        Monotonic wall clock, s.
    """

    def __init__(self, plant: Plant, *, time_source: Callable[[], float] = time.monotonic) -> None:
        self.plant = plant
        self._time_source = time_source
        self._lock = threading.Lock()
        self._origin_s: float | None = None
        self._plant_time_s = 0.0

    def start(self) -> None:
        """Let plant time run from now on (idempotent)."""
        with self._lock:
            if self._origin_s is None:
                self._origin_s = self._time_source() - self._plant_time_s

    @property
    def origin_s(self) -> float:
        """The time source's reading at plant time 0 (NaN before :meth:`start`)."""
        with self._lock:
            return self._origin_s if self._origin_s is not None else float("nan")

    @property
    def started(self) -> bool:
        """True once :meth:`start` was called."""
        return self._origin_s is not None

    def plant_time_s(self) -> float:
        """Current plant time (s): wall time since :meth:`start`, 0 before it."""
        with self._lock:
            self._sync()
            return self._plant_time_s

    def _sync(self) -> None:
        if self._origin_s is None:
            return
        target = self._time_source() - self._origin_s
        if target > self._plant_time_s:
            self.plant.advance_to(target)
            self._plant_time_s = target

    def call(self, action: Callable[[Plant], _T]) -> _T:
        """``action(plant)`` on the plant integrated to now, under the lock (other device faces)."""
        with self._lock:
            self._sync()
            return action(self.plant)

    def enable_motor(self) -> MotorState:
        """Motor mode on in the plant; its state now."""
        with self._lock:
            self._sync()
            return self.plant.motor.enable()

    def disable_motor(self) -> None:
        """Motor limp in the plant."""
        with self._lock:
            self._sync()
            self.plant.motor.disable()

    def command_motor(self, torque_nm: float) -> MotorState:
        """Apply ``torque_nm`` (spool side) from now on; the motor state now."""
        with self._lock:
            self._sync()
            state = self.plant.motor.command_torque(torque_nm)
        if state is None:  # a simulated motor answers at once: None would be a bug in the plant
            raise HardwareError("the simulated motor returned no state")
        return state

    def command_motor_mit(self, position_rad: float, velocity_rad_s: float, kp: float, kd: float,
                          torque_nm: float) -> MotorState:
        """Apply an MIT-mode command from now on, evaluated at every plant step as the motor's own
        loop does (``position_rad`` in the plant's spool coordinate); the motor state now."""
        with self._lock:
            self._sync()
            motor = self.plant.motor
            command = getattr(motor, "command_impedance", None)
            if command is None:
                raise HardwareError("this simulated motor takes torque commands only")
            state: MotorState = command(position_rad, velocity_rad_s, kp, kd, torque_nm)
            return state

    def elevation(self) -> ElevationSample | None:
        """The arm's elevation now (ground truth of the simulated IMU)."""
        with self._lock:
            self._sync()
            return self.plant.elevation_sensor.read()

    def tension(self) -> TensionSample | None:
        """The cable tension at the anchor now (ground truth of the simulated load cell)."""
        with self._lock:
            self._sync()
            return self.plant.tension_sensor.read()
