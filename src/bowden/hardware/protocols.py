"""The device protocols the runtime loop drives.

A real suit (AK60-6 over CAN, NGIMU over UDP, ADS1115 over I2C) and the simulated suit both implement
these. Units are SI, signs as docs/design.md: motor torque > 0 pulls the cable, spool velocity > 0 reels
it in, elevation velocity > 0 while raising. Devices are context managers: leaving the ``with`` block
leaves the suit safe (zero torque, motor mode exited) whatever happened inside it.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import TracebackType
from typing import Protocol, Self, runtime_checkable


@dataclass(frozen=True, slots=True)
class MotorState:
    """One motor reply, in output-shaft (spool) units.

    ``position_rad`` is multi-turn (wraps already counted); ``error_code`` is the driver's code
    (0 none; AK60-6: 1 over-temperature, 2 over-current, 3 over-voltage, 4 under-voltage,
    5 encoder, 6 phase imbalance).
    """

    time_s: float
    position_rad: float
    velocity_rad_s: float
    torque_nm: float
    temperature_c: float
    error_code: int = 0


@dataclass(frozen=True, slots=True)
class ElevationSample:
    """Humeral elevation from the upper-arm IMU at ``time_s`` (the sensor's sample time)."""

    time_s: float
    elevation_rad: float
    elevation_velocity_rad_s: float


@dataclass(frozen=True, slots=True)
class TensionSample:
    """Cable tension at the arm anchor from the load cell (evaluation only, never control)."""

    time_s: float
    tension_n: float


@runtime_checkable
class Clock(Protocol):
    """Monotonic time in seconds and a way to wait for an absolute deadline.

    The real clock sleeps; a simulated clock advances the simulated suit to the deadline instead, so
    the same loop runs a simulated trial faster than real time.
    """

    def now(self) -> float: ...

    def sleep_until(self, deadline_s: float) -> None: ...


@runtime_checkable
class Motor(Protocol):
    """A torque-controlled motor driving the spool."""

    def enable(self) -> MotorState:
        """Enter motor mode; returns the first state."""
        ...

    def disable(self) -> None:
        """Exit motor mode (motor limp). Safe to call more than once."""
        ...

    def set_zero(self) -> None:
        """Make the current position the zero of ``position_rad``."""
        ...

    def command_torque(self, torque_nm: float) -> MotorState | None:
        """Send a torque command (spool side, Nm) without waiting for its reply.

        Returns the newest state that arrived since the previous call (on a bus, the reply to the
        previous cycle's command serves this cycle), or None when no valid reply arrived since then.
        A simulated motor that answers at once returns the state after this command.
        """
        ...

    def __enter__(self) -> Self: ...

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...


@runtime_checkable
class ElevationSensor(Protocol):
    """The humeral elevation source (IMU). ``read`` never blocks: it returns the latest sample."""

    def read(self) -> ElevationSample | None:
        """The most recent sample, or None before the first one arrived."""
        ...

    def __enter__(self) -> Self: ...

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...


@runtime_checkable
class TensionSensor(Protocol):
    """The load cell. ``read`` never blocks: it returns the latest sample.

    ``failure`` is None while the sensor works, else why it was lost (its reader gave up); the loop
    reads it every cycle, so it must be a plain attribute or a cheap property.
    """

    @property
    def failure(self) -> str | None: ...

    def read(self) -> TensionSample | None:
        """The most recent sample, or None before the first one arrived."""
        ...

    def __enter__(self) -> Self: ...

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...
