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
* only the motor's replies are taken: classic standard data frames on ``reply_arbitration_id`` (the
  firmware's master id, 0 by default), 6 or 8 bytes long, byte 0 the motor id. Other frames
  (another id, extended id, remote, error or CAN FD frames, byte 0 another motor's id) are counted
  as foreign and ignored; a frame with the motor's ids but another length is a damaged reply,
  counted as malformed and skipped — never the end of a wait for a good one, never an exception;
* the ±12.5 rad position field is only ±2 output turns, so wraps are counted and ``position_rad`` is
  multi-turn spool position (the field wraps on the AK firmware; a jump of more than half the field
  between two replies is a wrap, which needs |v| < P·reply rate: 6000 rad/s at 500 Hz);
* transmit failures — typically ``No buffer space available`` (errno 105) when nothing on the bus
  acknowledges — raise :class:`~bowden.errors.TransmitError`: at once in the cycle (the loop counts
  them), after brief retries for enter/exit/zero; leaving the ``with`` block never raises for them
  (it records ``exit_error``). A read the interface refuses is counted and, in the cycle, is just
  no reply;
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

from bowden.errors import (
    DeviceTimeoutError,
    HardwareError,
    MalformedFrameError,
    ParameterError,
    TransmitError,
)
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
_REPLY_GAP_S = 0.005  # replies on a bus come within a fraction of a millisecond of each other


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

    replies: int = 0  # valid replies taken
    timeouts: int = 0  # blocking waits (enter, exit, zero) that ended without a valid reply
    malformed: int = 0  # frames on the reply id carrying our id that do not decode (wrong length)
    stale_replies: int = 0  # valid replies superseded by a newer one in the same poll
    foreign: int = 0  # frames that are not this motor's replies
    poll_limit_hits: int = 0  # polls that may have left frames on the bus (max_frames_per_poll taken)
    transmit_retries: int = 0
    transmit_failures: int = 0
    receive_errors: int = 0  # the interface refused a read (e.g. socketcan with the link down)


class AK60Motor:
    """An AK60-6 in MIT mode used as a torque source (implements :class:`~bowden.hardware.Motor`).

    Parameters
    ----------
    bus
        An open python-can bus at 1 Mbit/s; the caller owns it and shuts it down.
    config
        :class:`AK60Config`.
    clock
        Monotonic time source (s) used for reply deadlines, the send times of the reply accounting
        and state time stamps.

    Attributes
    ----------
    config
        The :class:`AK60Config` in use.
    counters
        :class:`AK60Counters`: replies taken, frames refused, polls cut short, transmit and receive
        failures.
    last_state
        The newest state taken from a valid reply (None before the first).
    unanswered_commands
        Torque commands awaiting a reply: those sent since the last valid reply was taken. A reply
        taken by :meth:`command_torque` is credited to the commands sent before it (it cannot be told
        from the reply to the command just sent), so that command stays pending and the count is 1
        after a call that returned a state; a reply of :meth:`enable`, :meth:`disable`,
        :meth:`set_zero` or :meth:`poll` answers everything and leaves 0.
    oldest_unanswered_send_s
        Clock time (s) at which the oldest of the unanswered commands was sent; NaN when none is.
        The loop judges motor silence by these two (replies missing to commands actually sent), so a
        pause of the host, which sends nothing, never looks like a silent motor.
    last_malformed
        Why the newest undecodable reply was refused, until a valid reply is taken (None then): the
        loop adds "(malformed frames)" to a no-reply stop while it is set.
    last_receive_error
        The interface's message for the newest refused read, until a read succeeds (None then).
    exit_error
        What went wrong leaving the ``with`` block (the bus refused the zero command or the exit
        frame), or None: leaving never raises for the bus, the caller reports this.
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
        self.unanswered_commands = 0
        self.oldest_unanswered_send_s = math.nan
        self.last_malformed: str | None = None
        self.last_receive_error: str | None = None
        self.exit_error: str | None = None
        self._exit_replies_expected = 0
        self._exit_deadline_s = -math.inf
        self._foreign_ids: set[int] = set()  # ids of foreign frames carrying our id in byte 0

    # --- Motor protocol ---------------------------------------------------------------------------
    @property
    def enabled(self) -> bool:
        """True between :meth:`enable` and :meth:`disable`."""
        return self._enabled

    def enable(self) -> MotorState:
        """Enter motor mode and return the state frame the motor answers with.

        Raises
        ------
        DeviceTimeoutError
            No valid reply to any of ``enter_attempts`` enter frames (the message names the CAN id
            that frames carrying the motor id came on, if they came on another one).
        TransmitError
            The enter frame could not be sent (after ``send_attempts``).
        HardwareError
            The interface refused to read.
        """
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
        return state

    def disable(self) -> None:
        """Exit motor mode (motor limp). Safe to call more than once and on a silent motor.

        The reply to the exit frame is read if it comes but not required: a motor that has gone
        silent must still be told to stop, and the caller cannot do more than that.

        Raises
        ------
        TransmitError
            The exit frame could not be sent (after ``send_attempts``).
        """
        self.request_exit()
        self.await_exit()

    def request_exit(self) -> None:
        """Send the exit frame now without waiting for its reply (:meth:`await_exit` waits); a caller
        stopping several motors sends every exit first, so that a silent one delays no other.

        Raises
        ------
        TransmitError
            The exit frame could not be sent (after ``send_attempts``).
        """
        # Replies to the last torque commands may still be on their way: the exit's reply is the one
        # after them (the motor answers in order).
        self._exit_replies_expected = self.unanswered_commands + 1
        self._send(EXIT_MOTOR_MODE)
        self._enabled = False
        self._exit_deadline_s = self._clock() + self.config.special_reply_timeout_s

    def await_exit(self) -> bool:
        """Read the replies up to the exit's, within ``special_reply_timeout_s`` of the request;
        True if the motor answered (False: the exit frame may not have reached it).

        The count can be one too many (a reply taken in the poll right after its own command is still
        counted pending), so once replies flow a short quiet gap ends the wait.
        """
        expected, self._exit_replies_expected = self._exit_replies_expected, 0
        received = 0
        while received < expected:
            remaining = max(self._exit_deadline_s - self._clock(), 0.0)
            try:
                self._await_state(remaining if received == 0 else min(remaining, _REPLY_GAP_S),
                                  "exit motor mode")
            except HardwareError as error:
                if received == 0:
                    _log.warning("AK60 id %d: no valid reply to exit motor mode (%s)",
                                 self.config.motor_id, error)
                return received > 0
            received += 1
        return True

    def set_zero(self) -> None:
        """Make the current position zero; waits out the motor's silence after the request.

        Raises
        ------
        DeviceTimeoutError
            If the motor has not answered within ``zero_timeout_s``.
        TransmitError
            A frame could not be sent (after ``send_attempts``).
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
            self.last_state = self._to_state(reply, self._unwrap(reply.position_rad))
            return

    def command_torque(self, torque_nm: float) -> MotorState | None:
        """Send a pure torque command (spool side, Nm, > 0 pulls) without waiting for its reply.

        One non-blocking send attempt, then the frames that have arrived are taken (at most
        ``max_frames_per_poll``; the rest are taken by the next call), waiting at most
        ``reply_wait_s`` (default 0) for a valid reply.

        Returns
        -------
        MotorState or None
            The newest valid state that arrived since the previous call — on a bus, the reply to an
            earlier command serves this cycle — or None when none did. Frames that are not this
            motor's replies, or do not decode, are counted and skipped, never raised.

        Raises
        ------
        TransmitError
            The frame could not be sent (one attempt, no retry, no wait: the loop counts failures).
        ParameterError
            ``torque_nm`` is NaN (a NaN command never reaches the wire).
        """
        if math.isnan(torque_nm):
            raise ParameterError("command_torque: torque_nm is NaN")
        limit = self.config.torque_limit_nm
        motor_torque = self.config.direction * min(max(torque_nm, -limit), limit)
        return self._command(MitCommand(torque_nm=motor_torque, kd=self.config.kd))

    def command_mit(
        self,
        position_rad: float,
        velocity_rad_s: float,
        kp: float,
        kd: float,
        torque_nm: float = 0.0,
    ) -> MotorState | None:
        """Send an MIT-mode command, τ = kp·(p − position) + kd·(v − velocity) + τ_ff, evaluated by
        the motor's own loop; non-blocking like :meth:`command_torque` (same return and errors).

        ``position_rad`` is the multi-turn spool position of :attr:`MotorState.position_rad` (suit
        sign). It is sent relative to the newest reported position, in the encoder field the motor
        compares it with, so the field's wrap never turns into a jump of the target; a target further
        than the field's half span from the motor is refused (a trajectory that far ahead is a bug).
        Velocity tracking (the bench) is ``kp`` > 0 with the target advancing at ``velocity_rad_s``;
        ``kp`` = 0 is a pure velocity command. The feed-forward torque is clamped like
        :meth:`command_torque`'s; ``kp``, ``kd`` must lie within the firmware's gain fields.
        """
        values = (position_rad, velocity_rad_s, kp, kd, torque_nm)
        if not all(math.isfinite(v) for v in values):
            raise ParameterError(f"command_mit: every value must be finite, got {values!r}")
        limits = self.config.limits
        if not (0.0 <= kp <= limits.kp_max and 0.0 <= kd <= limits.kd_max):
            raise ParameterError(f"command_mit: kp must be in [0, {limits.kp_max}] and kd in "
                                 f"[0, {limits.kd_max}], got kp={kp}, kd={kd}")
        sign = self.config.direction
        target = 0.0
        if kp > 0.0:
            last, raw = self.last_state, self._last_raw_position
            if last is None or raw is None:
                raise ParameterError("command_mit: a position target needs a reported position first "
                                     "(enable the motor)")
            offset = sign * (position_rad - last.position_rad)
            if abs(offset) > limits.position_rad:
                raise ParameterError(f"command_mit: target {offset:+.2f} rad from the motor's position "
                                     f"(at most ±{limits.position_rad:g})")
            target = min(max(raw + offset, -limits.position_rad), limits.position_rad)
        limit = self.config.torque_limit_nm
        command = MitCommand(position_rad=target, velocity_rad_s=sign * velocity_rad_s, kp=kp, kd=kd,
                             torque_nm=sign * min(max(torque_nm, -limit), limit))
        return self._command(command)

    def _command(self, command: MitCommand) -> MotorState | None:
        """One non-blocking send of ``command``, then the replies that have arrived (see above)."""
        sent_s = self._clock()
        self._send(pack_command(command, self.config.limits), attempts=1, timeout_s=0.0)
        state = self._poll(self.config.reply_wait_s)
        if state is not None:
            # The reply answers the commands before this one; this one now waits for its own.
            self.unanswered_commands = 1
            self.oldest_unanswered_send_s = sent_s
        else:
            if self.unanswered_commands == 0:
                self.oldest_unanswered_send_s = sent_s
            self.unanswered_commands += 1
        return state

    def poll(self, wait_s: float = 0.0) -> MotorState | None:
        """The newest valid state among the frames that arrived, waiting at most ``wait_s`` for one,
        without sending anything (tools and tests; the loop uses :meth:`command_torque`).

        A valid reply taken here answers every command sent so far (``unanswered_commands`` = 0).
        """
        if not (math.isfinite(wait_s) and wait_s >= 0.0):
            raise ParameterError(f"poll: wait_s must be ≥ 0, got {wait_s!r}")
        state = self._poll(wait_s)
        if state is not None:
            self._all_answered()
        return state

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        """Leave motor mode if still in it. Never raises for the bus: the caller reports ``exit_error``.

        A zero-torque command goes first; whether or not it could be sent, the exit frame is tried
        (with its retries): it is what leaves the motor limp.
        """
        if not self._enabled:
            return
        problems: list[str] = []
        try:
            self.command_torque(0.0)
        except (HardwareError, can.CanError) as error:
            problems.append(f"zero command: {error}")
        exit_sent = False
        try:
            self.disable()
            exit_sent = True
        except (HardwareError, can.CanError) as error:
            problems.append(f"exit motor mode: {error}")
        if not problems:
            return
        if exit_sent:  # only the zero command before the exit frame failed
            self.exit_error = "left motor mode, but the " + "; ".join(problems)
            _log.warning("AK60 id %d: %s", self.config.motor_id, self.exit_error)
        else:
            self.exit_error = "could not leave motor mode: " + "; ".join(problems)
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

    def _recv(self, timeout_s: float) -> can.Message | None:
        """One frame within ``timeout_s``, or None; a refused read raises :class:`HardwareError`."""
        try:
            message = self._bus.recv(timeout=timeout_s)
        except can.CanError as error:
            self.counters.receive_errors += 1
            if self.last_receive_error is None:  # said once per outage, not every cycle
                _log.warning("AK60 id %d: CAN receive failed: %s", self.config.motor_id, error)
            self.last_receive_error = str(error)
            raise HardwareError(f"AK60 id {self.config.motor_id}: CAN receive failed: {error}") from error
        self.last_receive_error = None
        return message

    def _discard_waiting(self, limit: int = 1000) -> None:
        """Drop frames queued before a request, so that its answer is not taken from them."""
        for _ in range(limit):
            if self._recv(0.0) is None:
                return

    def _is_reply(self, message: can.Message) -> bool:
        """From our motor: a classic standard data frame on the reply id, byte 0 our id.

        Its length, 6 or 8 bytes, is the decoder's to check: a frame that carries our ids but another
        length is a damaged reply (counted as malformed), not another node's frame.
        """
        data = message.data
        mine = (
            not (message.is_error_frame or message.is_remote_frame or message.is_extended_id or message.is_fd)
            and len(data) > 0
            and data[0] == self.config.motor_id
        )
        wanted = self.config.reply_arbitration_id
        if mine and (wanted is None or message.arbitration_id == wanted):
            return True
        self.counters.foreign += 1
        if mine:
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
        return reply

    def _poll(self, wait_s: float) -> MotorState | None:
        """The newest valid state among the frames that arrived (at most ``max_frames_per_poll``),
        waiting at most ``wait_s`` for one. Never raises for what is on the bus or a refused read.

        Every valid reply goes through the wrap counter in order, the superseded ones too, so that
        a poll taking several replies cannot miss a wrap between them.
        """
        newest: MitReply | None = None
        position = math.nan
        deadline = self._clock() + wait_s if wait_s > 0.0 else -math.inf
        for _ in range(self.config.max_frames_per_poll):
            remaining = deadline - self._clock() if newest is None and wait_s > 0.0 else 0.0
            try:
                message = self._recv(max(remaining, 0.0))
            except HardwareError:
                break  # counted; the loop sees the missing replies
            if message is None:
                break
            if not self._is_reply(message):
                continue
            reply = self._decode(message)
            if reply is None:
                continue
            if newest is not None:
                self.counters.stale_replies += 1
            newest = reply
            position = self._unwrap(reply.position_rad)
        else:
            self.counters.poll_limit_hits += 1
        if newest is None:
            return None
        state = self._to_state(newest, position)
        self.last_state = state
        return state

    def _await_reply(self, timeout_s: float) -> MitReply:
        """The first valid reply within ``timeout_s`` (enter/exit/zero); bad frames do not end the wait.

        The reply answers every command sent before it (the motor answers in order).
        """
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
                elif self.last_malformed is not None:
                    hint = f"; frames with its ids did not decode ({self.last_malformed})"
                raise DeviceTimeoutError(
                    f"AK60 id {self.config.motor_id}: no reply within {timeout_s * 1e3:.1f} ms{hint}"
                )
            message = self._recv(remaining)
            if message is None or not self._is_reply(message):
                continue
            reply = self._decode(message)
            if reply is not None:
                self._all_answered()
                return reply

    def _await_state(self, timeout_s: float, what: str) -> MotorState:
        try:
            reply = self._await_reply(timeout_s)
        except DeviceTimeoutError as error:
            raise DeviceTimeoutError(f"{error} ({what})") from None
        state = self._to_state(reply, self._unwrap(reply.position_rad))
        self.last_state = state
        return state

    def _all_answered(self) -> None:
        self.unanswered_commands = 0
        self.oldest_unanswered_send_s = math.nan

    def _unwrap(self, raw: float) -> float:
        """Multi-turn position (motor side, rad) of a raw ±P field reading; counts the wraps."""
        previous = self._last_raw_position
        if previous is not None:
            jump = raw - previous
            if jump > 0.5 * self._field_span_rad:
                self._turns -= 1
            elif jump < -0.5 * self._field_span_rad:
                self._turns += 1
        self._last_raw_position = raw
        return raw + self._turns * self._field_span_rad

    def _to_state(self, reply: MitReply, position_rad: float) -> MotorState:
        sign = self.config.direction
        return MotorState(
            time_s=self._clock(),
            position_rad=sign * position_rad,
            velocity_rad_s=sign * reply.velocity_rad_s,
            torque_nm=sign * reply.torque_nm,
            temperature_c=reply.temperature_c,
            error_code=reply.error_code,
        )
