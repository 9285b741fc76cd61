"""The AK60-6 V1.1 MIT-mode driver over an injected ``can.BusABC``.

The bus is injected (socketcan ``can0`` on the BeagleBone, python-can's ``virtual`` bus against the
simulated peer in tests), never opened here. Frames are those of :mod:`bowden.hardware.ak60_codec`.

What the driver adds to the codec:

* :meth:`AK60Motor.command_torque` never waits for its reply (by default; at most
  ``reply_wait_s``): it sends, takes the frames that have arrived (at most ``max_frames_per_poll``,
  so a node flooding the bus cannot hold the loop) and returns the newest valid reply, or None. The
  reply to cycle k's command thus serves cycle k + 1. The driver counts the commands sent since the
  last valid reply and when the oldest of them went out, which is what the loop's no-reply watchdog
  judges (a stall of the host sends nothing, so it cannot look like a silent motor);
* only the motor's replies are taken: standard data frames on ``reply_arbitration_id`` (the
  firmware's master id, 0 by default), 6 or 8 bytes long, byte 0 the motor id. Other frames are
  counted as foreign and ignored; a reply that does not decode is counted and skipped, never the end
  of a wait for a good one;
* the ±12.5 rad position field is only ±2 output turns, so wraps are counted and ``position_rad`` is
  multi-turn spool position (the field wraps on the AK firmware; a jump of more than half the field
  between two replies is a wrap, which needs |v| < P·reply rate: 6000 rad/s at 500 Hz);
* transmit failures — typically ``No buffer space available`` (errno 105) when nothing on the bus
  acknowledges — raise :class:`~bowden.errors.TransmitError`: at once in the cycle (the loop counts
  them), after brief retries for enter/exit/zero; leaving the ``with`` block never raises for them;
* motor error codes are passed through in :attr:`MotorState.error_code` (the loop's watchdog turns
  them into a safe stop), never swallowed;
* ``direction`` maps the motor's positive sense onto the suit's (torque > 0 pulls the cable).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from types import TracebackType
from typing import Self

import can

from bowden.errors import DeviceTimeoutError, MalformedFrameError, ParameterError, TransmitError
from bowden.hardware.ak60_codec import (
    DEFAULT_FIRMWARE,
    ENTER_MOTOR_MODE,
    EXIT_MOTOR_MODE,
    FIRMWARE_LIMITS,
    MAX_STANDARD_ID,
    SET_ZERO,
    AK60Limits,
    MitCommand,
    MitReply,
    pack_command,
    unpack_reply,
)
from bowden.hardware.protocols import MotorState

_log = logging.getLogger(__name__)
ERRNO_NO_BUFFER_SPACE = 105  # ENOBUFS on Linux: the CAN controller's transmit queue is full
MAX_REPLY_WAIT_S = 0.0005


@dataclass(frozen=True, kw_only=True)
class AK60Config:
    """How to talk to one AK60-6 (all times in seconds).

    Parameters
    ----------
    motor_id
        CAN id of the motor (standard 11-bit; the reply carries it in byte 0).
    limits
        Field ranges of the firmware variant (see ``ak60_codec.FIRMWARE_LIMITS``).
    reply_timeout_s
        Send timeout, and how long :meth:`AK60Motor.set_zero` polls wait for a reply.
    reply_wait_s
        How long a torque command may wait for a reply to arrive (default 0: it takes what has
        arrived). A round trip on a 1 Mbit/s bus is ≈ 0.25 ms, so 0.0003 lets a cycle use its own
        reply; at most 0.5 ms, a small part of the period.
    max_frames_per_poll
        Frames taken from the bus per torque command at most (the rest wait for the next one).
    special_reply_timeout_s
        How long enter/exit motor mode wait for the motor's state frame.
    enter_attempts
        Enter motor mode is sent up to this many times before the motor counts as silent: a frame
        lost on the bus, or a reply late because the host was busy, must not abort a session
        (entering motor mode twice is harmless).
    zero_settle_s, zero_timeout_s
        After "set zero" the motor is silent ~0.5–1.5 s: wait ``zero_settle_s``, then poll until it
        answers or ``zero_timeout_s`` has passed since the request.
    direction
        +1 if positive motor torque pulls the cable, −1 if the spool is wound the other way.
    torque_limit_nm
        Commands are clamped to ±this (Nm, spool side) before packing. Default: the peak torque.
    kd
        Damping gain sent with every torque command (Nm·s/rad); 0 = pure torque control.
    reply_arbitration_id
        Accept replies only on this CAN id (the firmware's "master id", 0 by default on the
        AK-series firmware), or None to accept any standard id (not recommended: any node whose
        frame starts with the motor id would be taken for the motor).
    send_attempts, send_retry_s
        A failed transmit is retried this many times in all, ``send_retry_s`` apart.
    """

    motor_id: int = 1
    limits: AK60Limits = field(default_factory=lambda: FIRMWARE_LIMITS[DEFAULT_FIRMWARE])
    reply_timeout_s: float = 0.01
    reply_wait_s: float = 0.0
    max_frames_per_poll: int = 32
    special_reply_timeout_s: float = 0.1
    zero_settle_s: float = 0.5
    zero_timeout_s: float = 2.0
    direction: int = 1
    torque_limit_nm: float = 9.0
    kd: float = 0.0
    reply_arbitration_id: int | None = 0
    send_attempts: int = 3
    send_retry_s: float = 0.0002
    enter_attempts: int = 3

    def __post_init__(self) -> None:
        if not 0 < self.motor_id <= MAX_STANDARD_ID:
            raise ParameterError(f"AK60Config.motor_id must be in 1..{MAX_STANDARD_ID}, got {self.motor_id}")
        for name in ("reply_timeout_s", "special_reply_timeout_s", "zero_timeout_s", "torque_limit_nm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ParameterError(f"AK60Config.{name} must be positive, got {value!r}")
        for name in ("zero_settle_s", "kd", "send_retry_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ParameterError(f"AK60Config.{name} must be non-negative, got {value!r}")
        if self.zero_settle_s >= self.zero_timeout_s:
            raise ParameterError("AK60Config.zero_settle_s must be shorter than zero_timeout_s")
        if self.direction not in (1, -1):
            raise ParameterError(f"AK60Config.direction must be +1 or -1, got {self.direction}")
        if self.kd > self.limits.kd_max:
            raise ParameterError(f"AK60Config.kd ({self.kd}) exceeds limits.kd_max ({self.limits.kd_max})")
        if self.send_attempts < 1:
            raise ParameterError(f"AK60Config.send_attempts must be >= 1, got {self.send_attempts}")
        if not (math.isfinite(self.reply_wait_s) and 0.0 <= self.reply_wait_s <= MAX_REPLY_WAIT_S):
            raise ParameterError(f"AK60Config.reply_wait_s must be in [0, {MAX_REPLY_WAIT_S}] s, "
                                 f"got {self.reply_wait_s!r}")
        if self.max_frames_per_poll < 1:
            raise ParameterError(
                f"AK60Config.max_frames_per_poll must be >= 1, got {self.max_frames_per_poll}"
            )
        if self.enter_attempts < 1:
            raise ParameterError(f"AK60Config.enter_attempts must be >= 1, got {self.enter_attempts}")
        if self.reply_arbitration_id is not None and not 0 <= self.reply_arbitration_id <= MAX_STANDARD_ID:
            raise ParameterError(
                f"AK60Config.reply_arbitration_id must be a standard id, got {self.reply_arbitration_id}"
            )


@dataclass
class AK60Counters:
    """What went wrong so far (for the run summary and the tests)."""

    replies: int = 0
    timeouts: int = 0
    malformed: int = 0
    stale_replies: int = 0  # valid replies superseded by a newer one in the same poll
    foreign: int = 0  # frames that are not this motor's replies
    poll_limit_hits: int = 0  # polls that left frames on the bus (max_frames_per_poll reached)
    transmit_retries: int = 0
    transmit_failures: int = 0


class AK60Motor:
    """An AK60-6 in MIT mode used as a torque source (implements :class:`~bowden.hardware.Motor`).

    Parameters
    ----------
    bus
        An open python-can bus at 1 Mbit/s; the caller owns it and shuts it down.
    config
        :class:`AK60Config`.
    clock
        Monotonic time source (s) used for reply deadlines and state time stamps.
    """

    def __init__(
        self,
        bus: can.BusABC,
        config: AK60Config | None = None,
        *,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._bus = bus
        self.config = config if config is not None else AK60Config()
        self._clock = clock
        self.counters = AK60Counters()
        self._enabled = False
        self._last_raw_position: float | None = None
        self._turns = 0
        self._field_span_rad = 2.0 * self.config.limits.position_rad
        self.last_state: MotorState | None = None
        self.unanswered_commands = 0  # torque commands sent since the last valid reply
        self.oldest_unanswered_send_s = math.nan  # clock time of the first of them
        self.last_malformed: str | None = None  # why the newest undecodable reply was refused
        self.exit_error: str | None = None  # what went wrong leaving the ``with`` block
        self._foreign_ids: set[int] = set()  # ids of foreign frames carrying our id in byte 0

    # --- Motor protocol ---------------------------------------------------------------------------
    @property
    def enabled(self) -> bool:
        """True between :meth:`enable` and :meth:`disable`."""
        return self._enabled

    def enable(self) -> MotorState:
        """Enter motor mode and return the state frame the motor answers with."""
        self._discard_waiting()
        attempt = 1
        while True:
            self._send(ENTER_MOTOR_MODE)
            try:
                state = self._await_state(self.config.special_reply_timeout_s, "enter motor mode")
                break
            except DeviceTimeoutError:
                if attempt == self.config.enter_attempts:
                    raise
                _log.warning("AK60 id %d: no reply to enter motor mode (attempt %d of %d); sending it again",
                             self.config.motor_id, attempt, self.config.enter_attempts)
                attempt += 1
        self._enabled = True
        self.unanswered_commands = 0
        self.oldest_unanswered_send_s = math.nan
        return state

    def disable(self) -> None:
        """Exit motor mode (motor limp). Safe to call more than once and on a silent motor.

        The reply to the exit frame is read if it comes but not required: a motor that has gone
        silent must still be told to stop, and the caller cannot do more than that.
        """
        # Replies to the last torque commands may still be on their way: the exit's reply is the one
        # after them (the motor answers in order), so wait for all of them, within the timeout.
        expected = self.unanswered_commands + 1
        self._send(EXIT_MOTOR_MODE)
        self._enabled = False
        deadline = self._clock() + self.config.special_reply_timeout_s
        received = 0
        while received < expected:
            try:
                self._await_state(max(deadline - self._clock(), 0.0), "exit motor mode")
            except (DeviceTimeoutError, MalformedFrameError) as error:
                if received == 0:
                    _log.warning("AK60 id %d: no valid reply to exit motor mode (%s)",
                                 self.config.motor_id, error)
                return
            received += 1

    def set_zero(self) -> None:
        """Make the current position zero; waits out the motor's silence after the request.

        Raises
        ------
        DeviceTimeoutError
            If the motor has not answered within ``zero_timeout_s``.
        """
        requested_s = self._clock()
        self._send(SET_ZERO)
        time.sleep(self.config.zero_settle_s)
        poll = MitCommand(torque_nm=0.0) if self._enabled else None
        while True:
            remaining = requested_s + self.config.zero_timeout_s - self._clock()
            if remaining <= 0.0:
                raise DeviceTimeoutError(
                    f"AK60 id {self.config.motor_id} did not answer within {self.config.zero_timeout_s} s "
                    "after set-zero; check power and wiring, then retry"
                )
            # A zero-torque command (motor mode) or a repeated exit frame (rest) is harmless either way.
            self._send(pack_command(poll, self.config.limits) if poll is not None else EXIT_MOTOR_MODE)
            try:
                reply = self._await_reply(min(remaining, self.config.reply_timeout_s * 5))
            except DeviceTimeoutError:
                continue
            # The motor's zero is now here; forget the wrap history measured against the old one.
            self._turns = 0
            self._last_raw_position = None
            self.last_state = self._to_state(reply)
            return

    def command_torque(self, torque_nm: float) -> MotorState | None:
        """Send a pure torque command (spool side, Nm, > 0 pulls) without waiting for its reply.

        Returns the newest valid state that arrived since the previous call — the reply to an
        earlier command — or None when none did (waits at most ``reply_wait_s`` for one).

        Raises
        ------
        TransmitError
            The frame could not be sent (one attempt, no retry: the loop counts failures).
        ParameterError
            ``torque_nm`` is NaN (a NaN command never reaches the wire).
        """
        if math.isnan(torque_nm):
            raise ParameterError("command_torque: torque_nm is NaN")
        limit = self.config.torque_limit_nm
        motor_torque = self.config.direction * min(max(torque_nm, -limit), limit)
        command = MitCommand(torque_nm=motor_torque, kd=self.config.kd)
        sent_s = self._clock()
        self._send(pack_command(command, self.config.limits), attempts=1, timeout_s=0.0)
        if self.unanswered_commands == 0:
            self.oldest_unanswered_send_s = sent_s
        self.unanswered_commands += 1
        reply = self._poll(self.config.reply_wait_s)
        if reply is None:
            return None
        state = self._to_state(reply)
        self.last_state = state
        return state

    def poll(self, wait_s: float = 0.0) -> MotorState | None:
        """The newest valid state among the frames that arrived, waiting at most ``wait_s`` for one,
        without sending anything (tools and tests; the loop uses :meth:`command_torque`)."""
        if not (math.isfinite(wait_s) and wait_s >= 0.0):
            raise ParameterError(f"poll: wait_s must be ≥ 0, got {wait_s!r}")
        reply = self._poll(wait_s)
        if reply is None:
            return None
        state = self._to_state(reply)
        self.last_state = state
        return state

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        """Leave motor mode if still in it. Never raises for the bus: the caller reports ``exit_error``."""
        if not self._enabled:
            return
        try:
            self.command_torque(0.0)
            self.disable()
        except TransmitError as error:
            self.exit_error = f"could not leave motor mode: {error}"
            _log.error("AK60 id %d: %s", self.config.motor_id, self.exit_error)

    # --- wire ------------------------------------------------------------------------------------
    def _send(self, data: bytes, *, attempts: int | None = None, timeout_s: float | None = None) -> None:
        message = can.Message(arbitration_id=self.config.motor_id, data=data, is_extended_id=False)
        attempts = self.config.send_attempts if attempts is None else attempts
        timeout = self.config.reply_timeout_s if timeout_s is None else timeout_s
        last_error: can.CanError | None = None
        for attempt in range(attempts):
            try:
                self._bus.send(message, timeout=timeout)
                return
            except can.CanError as error:  # CanOperationError carries errno 105 on socketcan
                last_error = error
                if attempt + 1 < attempts:
                    self.counters.transmit_retries += 1
                    time.sleep(self.config.send_retry_s)
        self.counters.transmit_failures += 1
        hint = ""
        if getattr(last_error, "error_code", None) == ERRNO_NO_BUFFER_SPACE:
            hint = " (no buffer space: nothing acknowledges — is the motor powered, the bus terminated?)"
        tries = f" after {attempts} attempts" if attempts > 1 else ""
        raise TransmitError(
            f"AK60 id {self.config.motor_id}: transmit failed{tries}: {last_error}{hint}"
        ) from last_error

    def _discard_waiting(self, limit: int = 1000) -> None:
        """Drop frames queued before a request, so that its answer is not taken from them."""
        for _ in range(limit):
            if self._bus.recv(timeout=0.0) is None:
                return

    def _is_reply(self, message: can.Message) -> bool:
        """From our motor: a standard data frame on the reply id, byte 0 our id (its length, 6 or 8
        bytes, is the decoder's to check: a wrong one is a malformed reply, not a foreign frame)."""
        data = message.data
        mine = (
            not (message.is_error_frame or message.is_remote_frame or message.is_extended_id)
            and len(data) > 0
            and data[0] == self.config.motor_id
        )
        wanted = self.config.reply_arbitration_id
        if mine and (wanted is None or message.arbitration_id == wanted):
            return True
        self.counters.foreign += 1
        if data and data[0] == self.config.motor_id and not message.is_extended_id:
            self._foreign_ids.add(message.arbitration_id)
        return False

    def _decode(self, message: can.Message) -> MitReply | None:
        """The reply in ``message``, or None (counted) if it does not decode."""
        try:
            reply = unpack_reply(message.data, self.config.limits)
        except MalformedFrameError as error:
            self.counters.malformed += 1
            self.last_malformed = str(error)
            return None
        self.counters.replies += 1
        self.last_malformed = None
        self.unanswered_commands = 0
        self.oldest_unanswered_send_s = math.nan
        return reply

    def _poll(self, wait_s: float) -> MitReply | None:
        """The newest valid reply among the frames that arrived (bounded), waiting at most ``wait_s``."""
        newest: MitReply | None = None
        deadline = self._clock() + wait_s
        for _ in range(self.config.max_frames_per_poll):
            remaining = deadline - self._clock() if newest is None else 0.0
            message = self._bus.recv(timeout=max(remaining, 0.0))
            if message is None:
                return newest
            if self._is_reply(message):
                reply = self._decode(message)
                if reply is not None:
                    if newest is not None:
                        self.counters.stale_replies += 1
                    newest = reply
        self.counters.poll_limit_hits += 1
        return newest

    def _await_reply(self, timeout_s: float) -> MitReply:
        """The first valid reply within ``timeout_s`` (enter/exit/zero); bad frames do not end the wait."""
        deadline = self._clock() + timeout_s
        while True:
            remaining = deadline - self._clock()
            if remaining <= 0.0:
                self.counters.timeouts += 1
                hint = ""
                if self._foreign_ids:
                    ids = ", ".join(f"{i:#x}" for i in sorted(self._foreign_ids))
                    hint = (f"; frames starting with its id came on CAN id {ids}, not on the reply id "
                            f"{self.config.reply_arbitration_id}: check the firmware's master id")
                raise DeviceTimeoutError(
                    f"AK60 id {self.config.motor_id}: no reply within {timeout_s * 1e3:.1f} ms{hint}"
                )
            message = self._bus.recv(timeout=remaining)
            if message is None or not self._is_reply(message):
                continue
            reply = self._decode(message)
            if reply is not None:
                return reply

    def _await_state(self, timeout_s: float, what: str) -> MotorState:
        try:
            reply = self._await_reply(timeout_s)
        except DeviceTimeoutError as error:
            raise DeviceTimeoutError(f"{error} ({what})") from None
        state = self._to_state(reply)
        self.last_state = state
        return state

    def _to_state(self, reply: MitReply) -> MotorState:
        raw = reply.position_rad
        previous = self._last_raw_position
        if previous is not None:
            jump = raw - previous
            if jump > 0.5 * self._field_span_rad:
                self._turns -= 1
            elif jump < -0.5 * self._field_span_rad:
                self._turns += 1
        self._last_raw_position = raw
        sign = self.config.direction
        return MotorState(
            time_s=self._clock(),
            position_rad=sign * (raw + self._turns * self._field_span_rad),
            velocity_rad_s=sign * reply.velocity_rad_s,
            torque_nm=sign * reply.torque_nm,
            temperature_c=reply.temperature_c,
            error_code=reply.error_code,
        )
