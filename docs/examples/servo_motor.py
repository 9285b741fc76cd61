"""Worked example of an actuator plug-in: a CubeMars AK motor in *servo* mode, current loop.

docs/hardware.md, "Plug in your own actuator", walks through it. One class implements the
:class:`bowden.hardware.Motor` protocol (:class:`ServoCurrentMotor`), one simulated peer answers on
the same CAN bus as the motor would (:class:`ServoCurrentPeer`); tests/hardware/test_motor_plugin.py
runs the controller's loop on the pair.

The wire (CubeMars *AK Series Actuator Driver Manual* V1.0.8 §5.1–5.2; the field scales as
neurobionics/TMotorCANControl ``servo_can.py`` reads them): extended 29-bit ids,
``id = (mode << 8) | driver id``; the current-loop command is mode 1 with the q-axis current as a
big-endian int32 in mA; the motor reports its state in mode 0x29 frames: position int16 (0.1°),
speed int16 (10 electrical rpm), current int16 (0.01 A), temperature int8 (°C), error code.
Output torque = current × torque constant × gear ratio (:mod:`bowden.hardware.motors`), the
speed is electrical: divided by the pole pairs (21 on the AK80-9's 36N42P motor) and the gear.
"""

from __future__ import annotations

import math
import struct
import threading
import time
from types import TracebackType
from typing import Final, Self

import can

from bowden.errors import DeviceTimeoutError, ParameterError, TransmitError
from bowden.hardware.motors import motor_model
from bowden.hardware.protocols import MotorState

SET_CURRENT: Final = 1  # CAN_PACKET_SET_CURRENT
STATUS: Final = 0x29  # the servo-mode state packet
POLE_PAIRS: Final = 21


class ServoCurrentMotor:
    """An AK motor in servo mode used as a torque source (the :class:`~bowden.hardware.Motor` protocol).

    Parameters
    ----------
    bus
        An open python-can bus at 1 Mbit/s (the caller owns it).
    motor_id
        The driver id (low byte of every frame's id).
    model
        The AK model, for the torque constant and the gear ratio.
    max_current_a
        Commands are clamped to ± this current.
    """

    def __init__(self, bus: can.BusABC, *, motor_id: int = 1, model: str = "AK80-9",
                 max_current_a: float = 15.0) -> None:
        if not 0 < motor_id <= 0xFF:
            raise ParameterError(f"motor_id must be 1–255, got {motor_id}")
        spec = motor_model(model)
        self._bus = bus
        self.motor_id = motor_id
        self.gear_ratio = spec.gear_ratio
        self.nm_per_a = spec.output_torque_constant_nm_per_a
        self.max_current_a = max_current_a
        self.exit_error: str | None = None  # read by bowden run's summary

    # --- the Motor protocol ----------------------------------------------------------------------
    def enable(self) -> MotorState:
        """Servo mode needs no mode switch: command zero current and wait for the first state."""
        self._send_current(0.0)
        deadline = time.monotonic() + 0.5
        while time.monotonic() < deadline:
            state = self._take(wait_s=0.01)
            if state is not None:
                return state
        raise DeviceTimeoutError(f"servo motor id {self.motor_id}: no state within 0.5 s of a command")

    def disable(self) -> None:
        """Zero current (the motor goes limp). Never raises: leaving the suit must not fail."""
        try:
            self._send_current(0.0)
        except TransmitError as error:
            self.exit_error = str(error)

    def set_zero(self) -> None:
        pass  # bowden counts the spool position from the first state; it never needs the zero

    def command_torque(self, torque_nm: float) -> MotorState | None:
        """Send the current for ``torque_nm`` without waiting; the newest state that arrived, or None."""
        if math.isnan(torque_nm):
            raise ParameterError("cannot command a NaN torque")
        self._send_current(torque_nm / self.nm_per_a)
        return self._take(wait_s=0.0)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.disable()

    # --- the wire --------------------------------------------------------------------------------
    def _send_current(self, current_a: float) -> None:
        current_a = min(max(current_a, -self.max_current_a), self.max_current_a)
        message = can.Message(arbitration_id=(SET_CURRENT << 8) | self.motor_id, is_extended_id=True,
                              data=struct.pack(">i", round(current_a * 1000.0)))
        try:
            self._bus.send(message, timeout=0.0)
        except can.CanError as error:
            raise TransmitError(f"servo motor id {self.motor_id}: send failed ({error})") from None

    def _take(self, wait_s: float) -> MotorState | None:
        """The newest state among the frames waiting (at most 32: a flooded bus cannot hold the loop)."""
        newest = None
        for index in range(32):
            message = self._bus.recv(timeout=wait_s if index == 0 else 0.0)
            if message is None:
                break
            if (message.is_extended_id and message.arbitration_id == (STATUS << 8) | self.motor_id
                    and len(message.data) == 8):
                newest = self._decode(bytes(message.data))
        return newest

    def _decode(self, data: bytes) -> MotorState:
        position_01deg, speed_10erpm, current_10ma, temperature_c, error = struct.unpack(">hhhbB", data)
        return MotorState(
            time_s=time.monotonic(),
            position_rad=math.radians(position_01deg * 0.1),
            velocity_rad_s=speed_10erpm * 10.0 / POLE_PAIRS / self.gear_ratio * 2.0 * math.pi / 60.0,
            torque_nm=current_10ma * 0.01 * self.nm_per_a,
            temperature_c=float(temperature_c),
            error_code=error,
        )


class ServoCurrentPeer:
    """The motor's end of the bus: answers every current command with a state frame.

    Its "plant" is a first-order spool (inertia, viscous damping); ``applied_current_a`` is what it
    was last told, for the tests. A thread of its own, as the motor is a machine of its own.
    """

    def __init__(self, bus: can.BusABC, *, motor_id: int = 1, model: str = "AK80-9",
                 inertia_kg_m2: float = 2e-3, damping_nm_s: float = 0.05) -> None:
        spec = motor_model(model)
        self._bus = bus
        self.motor_id = motor_id
        self.gear_ratio = spec.gear_ratio
        self.nm_per_a = spec.output_torque_constant_nm_per_a
        self.inertia_kg_m2 = inertia_kg_m2
        self.damping_nm_s = damping_nm_s
        self.applied_current_a = 0.0
        self.position_rad = self.velocity_rad_s = 0.0
        self._last_s = time.monotonic()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="servo-peer", daemon=True)

    def __enter__(self) -> Self:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)

    def _serve(self) -> None:
        while not self._stop.is_set():
            message = self._bus.recv(timeout=0.05)
            if message is None or not message.is_extended_id:
                continue
            if message.arbitration_id != (SET_CURRENT << 8) | self.motor_id or len(message.data) != 4:
                continue
            self.applied_current_a = struct.unpack(">i", bytes(message.data))[0] / 1000.0
            self._advance()
            self._bus.send(can.Message(arbitration_id=(STATUS << 8) | self.motor_id, is_extended_id=True,
                                       data=self._state_bytes()))

    def _advance(self) -> None:
        now = time.monotonic()
        dt, self._last_s = min(now - self._last_s, 0.01), now
        torque_nm = self.applied_current_a * self.nm_per_a
        self.velocity_rad_s += (torque_nm - self.damping_nm_s * self.velocity_rad_s) / self.inertia_kg_m2 * dt
        self.position_rad += self.velocity_rad_s * dt

    def _state_bytes(self) -> bytes:
        erpm = self.velocity_rad_s * 60.0 / (2.0 * math.pi) * self.gear_ratio * POLE_PAIRS
        return struct.pack(">hhhbB", _int16(math.degrees(self.position_rad) * 10.0), _int16(erpm / 10.0),
                           _int16(self.applied_current_a * 100.0), 30, 0)


def _int16(value: float) -> int:
    """``value`` rounded and saturated to a signed 16-bit field (the motor's fields saturate too)."""
    return max(-32768, min(32767, round(value)))
