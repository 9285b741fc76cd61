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
    """A torque-controlled motor driving the spool — the interface an actuator plug-in implements.

    A lab with another actuator (an ODrive, a CubeMars motor in servo mode, ...) writes one class
    with these methods and hands it to :class:`~bowden.runtime.ControlLoop` (``motor=``); a worked
    example with its simulated peer is ``docs/examples/servo_motor.py`` (docs/hardware.md, "Plug in
    your own actuator"). The contract the loop relies on:

    * units and signs of the spool side: torque in Nm, > 0 pulls the cable; position (multi-turn)
      and velocity of the spool in rad and rad/s; ``MotorState.time_s`` on the loop's clock;
    * :meth:`command_torque` never blocks for long (the loop calls it every cycle, at up to 2 kHz):
      one send, and the replies that have already arrived; None when no new reply arrived — the
      loop's no-reply watchdog counts those cycles (``--motor-silence-ms``);
    * a failed send raises :class:`~bowden.errors.TransmitError` (the loop counts them: three in a
      row stop the suit); a NaN torque raises :class:`~bowden.errors.ParameterError`;
    * ``error_code`` ≠ 0 and the temperature are watched by the loop (``MOTOR_ERROR``,
      ``MOTOR_OVER_TEMPERATURE``): pass the device's own through, NaN for an unknown temperature;
    * :meth:`disable` and ``__exit__`` leave the motor limp and never raise (keep a failure in an
      ``exit_error`` attribute: ``bowden run`` prints it);
    * optional: ``command_mit(position_rad, velocity_rad_s, kp, kd, torque_nm)`` for the slack
      take-up in velocity mode, ``last_malformed`` (why the last frame was refused).
    """

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
