"""A simulated AK60-6 in MIT mode on a python-can bus.

It does what the firmware does (CubeMars driver manual V1.0.8 §5.3): listens for frames
addressed to its id, enters and leaves motor mode on the special frames, sets its zero (and is silent
for a while afterwards), turns each command into a torque τ = τ_ff + Kp(p_des − p) + Kd(v_des − v)
applied to the simulated plant while in motor mode, and answers every frame it heard with a real
reply frame (6 or 8 bytes, position wrapped into the ±P field like the real encoder count).

Fault injection for the tests: :meth:`AK60Peer.mute`, :meth:`AK60Peer.ignore_next`,
:meth:`AK60Peer.inject_error`, :meth:`AK60Peer.override_temperature`, :meth:`AK60Peer.replace_next_reply`,
:meth:`AK60Peer.garble_replies`, :meth:`AK60Peer.precede_next_reply`.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Final, Protocol, Self

import can

from bowden.errors import MalformedFrameError, ParameterError
from bowden.hardware.ak60_codec import (
    DEFAULT_FIRMWARE,
    ENTER_MOTOR_MODE,
    EXIT_MOTOR_MODE,
    FIRMWARE_LIMITS,
    SET_ZERO,
    AK60Limits,
    MitReply,
    pack_reply,
    unpack_command,
)
from bowden.hardware.lifecycle import StartedInWith, StoppableThread
from bowden.hardware.protocols import MotorState

ENTER: Final = "enter"
EXIT: Final = "exit"
ZERO: Final = "zero"
COMMAND: Final = "command"


class MotorPlant(Protocol):
    """What the peer drives: the suit's spool (:class:`WallTimePlant`) or the bench's mannequin joint."""

    def enable_motor(self) -> MotorState: ...

    def command_motor(self, torque_nm: float) -> MotorState: ...

    def command_motor_mit(self, position_rad: float, velocity_rad_s: float, kp: float, kd: float,
                          torque_nm: float) -> MotorState: ...


@dataclass(frozen=True, slots=True)
class ReceivedFrame:
    """What the peer heard: wall time (s), kind (enter/exit/zero/command) and, for commands, the
    torque it applied (Nm, motor sign, 0 outside motor mode)."""

    time_s: float
    kind: str
    torque_nm: float


class AK60Peer(StartedInWith):
    """The motor end of the CAN bus, backed by a simulated plant.

    Parameters
    ----------
    bus
        The peer's own bus (e.g. ``can.Bus(interface="virtual", channel=...)``); the caller owns it.
    plant
        What the motor drives: the shared simulated suit (:class:`WallTimePlant`), or the bench's
        mannequin joint (:class:`~bowden.sim.peers.mannequin.MannequinJoint`).
    motor_id
        CAN id it answers to.
    limits
        Field ranges of the firmware it pretends to run.
    reply_length
        6 (older firmware, no temperature or error byte) or 8.
    reply_arbitration_id
        CAN id of the replies (the firmware's "master id").
    zero_silence_s
        How long it stays silent after a set-zero frame.
    temperature_c
        Temperature reported when the plant does not say (NaN in its state).
    time_source
        Wall clock for the received-frame log.
    """

    def __init__(
        self,
        bus: can.BusABC,
        plant: MotorPlant,
        *,
        motor_id: int = 1,
        limits: AK60Limits | None = None,
        reply_length: int = 8,
        reply_arbitration_id: int = 0,
        zero_silence_s: float = 0.8,
        temperature_c: float = 35.0,
        time_source: Callable[[], float] = time.monotonic,
    ) -> None:
        if reply_length not in (6, 8):
            raise ParameterError(f"reply_length must be 6 or 8, got {reply_length}")
        if not 0.0 <= zero_silence_s < 10.0:
            raise ParameterError(f"zero_silence_s must be in [0, 10) s, got {zero_silence_s}")
        self._bus = bus
        self._plant = plant
        self.motor_id = motor_id
        self.limits = limits if limits is not None else FIRMWARE_LIMITS[DEFAULT_FIRMWARE]
        self.reply_length = reply_length
        self.reply_arbitration_id = reply_arbitration_id
        self.zero_silence_s = zero_silence_s
        self._default_temperature_c = temperature_c
        self._time_source = time_source
        self.received: deque[ReceivedFrame] = deque(maxlen=200_000)
        self.in_motor_mode = False
        self._zero_rad = 0.0
        self._silent_until = -math.inf
        self._muted = threading.Event()
        self._ignore_left = 0
        self._error_code = 0
        self._temperature_override: float | None = None
        self._last_state: MotorState | None = None
        self._applied_torque_nm = 0.0
        self._next_raw_reply: bytes | None = None
        self._preceding: list[can.Message] = []
        self._preceding_lock = threading.Lock()
        self._garbled = False
        self._server = StoppableThread(self._serve, f"ak60-peer-{self.motor_id}")

    # --- lifecycle -------------------------------------------------------------------------------
    def start(self) -> Self:
        """Start answering frames in a background thread."""
        if not self._server.running:
            self.power_on()
            self._server.start()
        return self

    def power_on(self) -> Self:
        """Power the plant's motor without a thread of its own: frames are then handed to
        :meth:`answer` by their bus (:class:`~bowden.sim.peers.inline_can.InlineCanBus`)."""
        # The plant's motor is the physics of a torque source: powered once, and "rest mode" is
        # zero torque, as the firmware commands zero current when not in motor mode.
        self._last_state = self._plant.enable_motor()
        return self

    def close(self) -> None:
        """Stop the thread (the bus stays open: its owner shuts it down)."""
        self._server.stop()

    # --- fault injection -------------------------------------------------------------------------
    def mute(self, muted: bool = True) -> None:
        """Stop (or resume) answering, as a motor that lost power or its bus connection."""
        if muted:
            self._muted.set()
        else:
            self._muted.clear()

    def ignore_next(self, count: int) -> None:
        """Let the next ``count`` frames to this motor go unanswered, as frames lost on the bus."""
        if count < 0:
            raise ParameterError(f"count must be >= 0, got {count}")
        self._ignore_left = count

    def inject_error(self, code: int) -> None:
        """Report ``code`` in byte 7 of every reply from now on (0 clears it)."""
        if not 0 <= code <= 0xFF:
            raise ParameterError(f"error code must fit one byte, got {code}")
        self._error_code = code

    def override_temperature(self, temperature_c: float | None) -> None:
        """Report this temperature (°C) from now on; None goes back to the plant's."""
        self._temperature_override = temperature_c

    def replace_next_reply(self, data: bytes) -> None:
        """Answer the next frame with these raw bytes instead of a proper reply (malformed-frame tests)."""
        self._next_raw_reply = data

    def precede_next_reply(self, frames: Iterable[can.Message]) -> None:
        """Put these frames on the bus just before the next reply, in order, as if other nodes (or a
        damaged transceiver) had sent them while the motor was answering: the driver finds them
        queued ahead of the reply, whatever the timing of the test."""
        frames = list(frames)
        with self._preceding_lock:
            self._preceding.extend(frames)

    def garble_replies(self, garbled: bool = True) -> None:
        """Answer every frame with an undecodable reply (right ids, 7 bytes: no firmware sends that),
        as a damaged transceiver would, from now on; False goes back to proper replies."""
        self._garbled = garbled

    # --- firmware --------------------------------------------------------------------------------
    def _serve(self) -> None:
        while not self._server.stop_requested.is_set():
            message = self._bus.recv(timeout=0.02)
            if message is not None:
                self.answer(message)

    def answer(self, message: can.Message) -> None:
        """Handle one frame heard on the bus as the firmware does (frames for other ids, extended,
        remote and error frames are not for it), replying on the bus."""
        if message.is_extended_id or message.is_error_frame:
            return
        if message.arbitration_id != self.motor_id or message.is_remote_frame:
            return
        self._handle(bytes(message.data))

    def _handle(self, data: bytes) -> None:
        if self._ignore_left > 0:
            self._ignore_left -= 1
            return
        now = self._time_source()
        if self._muted.is_set() or now < self._silent_until:
            return
        if data == ENTER_MOTOR_MODE:
            self.in_motor_mode = True
            self.received.append(ReceivedFrame(now, ENTER, 0.0))
            self._applied_torque_nm = 0.0
            state = self._plant.command_motor(0.0)
        elif data == EXIT_MOTOR_MODE:
            self.in_motor_mode = False
            self.received.append(ReceivedFrame(now, EXIT, 0.0))
            self._applied_torque_nm = 0.0
            state = self._plant.command_motor(0.0)
        elif data == SET_ZERO:
            self.received.append(ReceivedFrame(now, ZERO, 0.0))
            # Re-applying the torque being applied reads the state without changing what the motor does.
            state = self._plant.command_motor(self._applied_torque_nm)
            self._zero_rad = state.position_rad
            self._last_state = state
            self._silent_until = now + self.zero_silence_s
            return  # the real motor writes its flash and says nothing
        else:
            try:
                command = unpack_command(data, self.limits)
            except MalformedFrameError:
                return  # the firmware ignores frames it cannot read
            torque = 0.0
            last = self._last_state
            gains = command.kp > 0.0 or command.kd > 0.0
            if self.in_motor_mode:
                torque = command.torque_nm
                if last is not None and gains:
                    # What the motor's own loop applies now (for the log; the plant evaluates it at
                    # every step below). The target is in the wrapped field: rebase it on the plant.
                    error = command.position_rad - self._field_position(last.position_rad)
                    torque += command.kp * error
                    torque += command.kd * (command.velocity_rad_s - last.velocity_rad_s)
                torque = min(max(torque, -self.limits.torque_nm), self.limits.torque_nm)
            self.received.append(ReceivedFrame(now, COMMAND, torque))
            self._applied_torque_nm = torque
            if self.in_motor_mode and gains and last is not None:
                target = last.position_rad + command.position_rad - self._field_position(last.position_rad)
                state = self._plant.command_motor_mit(target, command.velocity_rad_s, command.kp,
                                                      command.kd, command.torque_nm)
            else:
                state = self._plant.command_motor(torque)
        self._last_state = state
        self._reply(state)

    def _reply(self, state: MotorState) -> None:
        with self._preceding_lock:
            preceding, self._preceding = self._preceding, []
        for frame in preceding:
            self._bus.send(frame)
        raw, self._next_raw_reply = self._next_raw_reply, None
        if raw is None and self._garbled:
            raw = bytes([self.motor_id]) + b"\xff" * 6
        if raw is not None:
            self._send(raw)
            return
        wrapped = self._field_position(state.position_rad)
        temperature = state.temperature_c
        if not math.isfinite(temperature):
            temperature = self._default_temperature_c
        if self._temperature_override is not None:
            temperature = self._temperature_override
        error = self._error_code or state.error_code
        reply = MitReply(
            motor_id=self.motor_id,
            position_rad=wrapped,
            velocity_rad_s=state.velocity_rad_s,
            torque_nm=state.torque_nm,
            temperature_c=temperature,
            error_code=error,
        )
        self._send(pack_reply(reply, self.limits, length=self.reply_length))

    def _field_position(self, plant_position_rad: float) -> float:
        """The encoder field's reading of a plant position: it wraps in ±P like the real motor's, so
        the driver must count turns."""
        half = self.limits.position_rad
        return (plant_position_rad - self._zero_rad + half) % (2.0 * half) - half

    def _send(self, data: bytes) -> None:
        self._bus.send(can.Message(arbitration_id=self.reply_arbitration_id, data=data, is_extended_id=False))

    def commands_since(self, time_s: float) -> list[ReceivedFrame]:
        """The frames heard at or after wall time ``time_s``, oldest first."""
        return [frame for frame in list(self.received) if frame.time_s >= time_s]
