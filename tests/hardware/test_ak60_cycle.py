"""The AK60 driver in the control cycle: it never blocks, reads a bounded number of frames and takes only
its motor's replies (against the simulated motor on python-can's virtual bus).

No verdict here depends on wall time. "Never blocks" is checked on the bus operations themselves (every
send and read of a cycle asks for timeout 0, and their number is bounded) and on a manual clock. The
frames of other nodes are put on the bus before the driver reads it (the virtual bus delivers a frame
during ``send``), with the simulated motor muted, so what one call finds is known exactly; frames that
must arrive with the motor's reply are sent by the peer itself just before it
(:meth:`AK60Peer.precede_next_reply`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import can
import pytest

from bowden.errors import DeviceTimeoutError, HardwareError, TransmitError
from bowden.hardware.ak60 import ERRNO_NO_BUFFER_SPACE, AK60Config, AK60Motor
from bowden.hardware.ak60_codec import (
    ENTER_MOTOR_MODE,
    EXIT_MOTOR_MODE,
    MitReply,
    pack_reply,
    position_resolution_rad,
    torque_resolution_nm,
    velocity_resolution_rad_s,
)
from bowden.hardware.protocols import MotorState
from bowden.sim.peers import AK60Peer, WallTimePlant
from bowden.sim.peers.ak60_peer import ENTER, EXIT

FAST = AK60Config(reply_timeout_s=0.05, special_reply_timeout_s=2.0, zero_settle_s=0.02, zero_timeout_s=5.0)
LIMITS = FAST.limits
MOTOR_ID = FAST.motor_id
REPLY_ID = 0  # the firmware's master id, which the peer answers on


class RecordingBus(can.BusABC):
    """The driver's end of the bus, recording every send and read with the timeout asked for.

    ``fail_sends`` sends from now on fail like socketcan when nothing acknowledges (errno 105);
    ``fail_reads`` reads fail like socketcan with the link down.
    """

    def __init__(self, inner: can.BusABC) -> None:
        super().__init__(channel="recording")
        self.inner = inner
        self.sends: list[tuple[bytes, float | None, bool]] = []  # (data, timeout, went out)
        self.reads: list[float | None] = []
        self.fail_sends = 0
        self.fail_reads = 0

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self.fail_sends > 0:
            self.fail_sends -= 1
            self.sends.append((bytes(msg.data), timeout, False))
            raise can.CanOperationError("Failed to transmit: [Errno 105] No buffer space available",
                                        error_code=ERRNO_NO_BUFFER_SPACE)
        self.sends.append((bytes(msg.data), timeout, True))
        self.inner.send(msg, timeout)

    def recv(self, timeout: float | None = None) -> can.Message | None:
        self.reads.append(timeout)
        if self.fail_reads > 0:
            self.fail_reads -= 1
            raise can.CanOperationError("Error receiving: [Errno 100] Network is down", error_code=100)
        return self.inner.recv(timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return self.inner.recv(timeout), False

    def clear(self) -> None:
        self.sends.clear()
        self.reads.clear()


class ManualClock:
    """The driver's clock: it moves only when the test moves it; counts how often it is read."""

    def __init__(self, now_s: float = 100.0) -> None:
        self.now_s = now_s
        self.reads = 0

    def __call__(self) -> float:
        self.reads += 1
        return self.now_s


@pytest.fixture
def peer(can_buses: tuple[can.BusABC, can.BusABC], wall_plant: WallTimePlant) -> Iterator[AK60Peer]:
    with AK60Peer(can_buses[1], wall_plant, zero_silence_s=0.05) as running:
        yield running


@pytest.fixture
def bus(can_buses: tuple[can.BusABC, can.BusABC]) -> Iterator[RecordingBus]:
    recording = RecordingBus(can_buses[0])
    try:
        yield recording
    finally:
        recording.shutdown()


@pytest.fixture
def intruder(can_buses: tuple[can.BusABC, can.BusABC]) -> can.BusABC:
    """Another node on the bus (the peer's end: the peer does not hear its own frames)."""
    return can_buses[1]


def reply_frame(position_rad: float = 0.0, *, velocity_rad_s: float = 0.0, torque_nm: float = 0.0,
                motor_id: int = MOTOR_ID, arbitration_id: int = REPLY_ID, length: int = 8) -> can.Message:
    """A reply frame as the firmware sends it."""
    reply = MitReply(motor_id=motor_id, position_rad=position_rad, velocity_rad_s=velocity_rad_s,
                     torque_nm=torque_nm, temperature_c=40.0, error_code=0)
    return can.Message(arbitration_id=arbitration_id, data=pack_reply(reply, LIMITS, length=length),
                       is_extended_id=False)


def garbled_frame() -> can.Message:
    """Our ids, 7 bytes: no firmware sends that (a damaged reply)."""
    return can.Message(arbitration_id=REPLY_ID, data=bytes([MOTOR_ID]) + b"\xff" * 6, is_extended_id=False)


def enabled_and_muted(motor: AK60Motor, peer: AK60Peer) -> None:
    """Motor mode on, then the motor silent: whatever the driver reads next was put there by the test."""
    motor.enable()
    peer.mute()


def next_reply(motor: AK60Motor, torque_nm: float = 0.0, timeout_s: float = 5.0) -> MotorState:
    """Command every 2 ms until a reply comes (the bound only keeps a broken driver from hanging)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        state = motor.command_torque(torque_nm)
        if state is not None:
            return state
        time.sleep(0.002)
    raise AssertionError("no reply")


# --- never blocks -------------------------------------------------------------------------------------
def test_a_silent_motor_never_holds_the_cycle(bus: RecordingBus, peer: AK60Peer) -> None:
    clock = ManualClock()
    motor = AK60Motor(bus, FAST, clock=clock)
    enabled_and_muted(motor, peer)
    bus.clear()
    reads_before = clock.reads
    clock.now_s = 500.0
    for k in range(1, 51):
        assert motor.command_torque(1.0) is None
        assert motor.unanswered_commands == k
        clock.now_s += 0.002
    # The oldest unanswered command is the first one sent after the last reply.
    assert motor.oldest_unanswered_send_s == 500.0
    # Per cycle: one send and one read, both asking not to wait at all; one clock read (the send time).
    assert len(bus.sends) == 50 and all(timeout == 0.0 and sent for _, timeout, sent in bus.sends)
    assert bus.reads == [0.0] * 50
    assert clock.reads - reads_before <= 50  # no waiting loop reading the clock
    assert motor.counters.transmit_retries == 0
    # The motor comes back: replies are taken again and the count starts over.
    peer.mute(False)
    clock.now_s = 600.0
    state = next_reply(motor, 0.5)
    assert state.error_code == 0
    # The reply answers the commands before the call that took it; that call's command waits for its own.
    assert motor.unanswered_commands == 1 and motor.oldest_unanswered_send_s == 600.0
    motor.disable()
    assert motor.unanswered_commands == 0 and math.isnan(motor.oldest_unanswered_send_s)


def test_a_failed_send_raises_at_once_and_is_not_an_unanswered_command(bus: RecordingBus,
                                                                       peer: AK60Peer) -> None:
    motor = AK60Motor(bus, FAST)
    enabled_and_muted(motor, peer)
    motor.command_torque(1.0)
    bus.clear()
    bus.fail_sends = 100
    with pytest.raises(TransmitError, match="no buffer space"):
        motor.command_torque(1.0)
    # One attempt that asked not to wait, no retry, no read: the loop gets the failure at once.
    assert bus.sends == [(bus.sends[0][0], 0.0, False)] and bus.reads == []
    assert motor.counters.transmit_failures == 1 and motor.counters.transmit_retries == 0
    assert motor.unanswered_commands == 1  # only the command that went out
    bus.fail_sends = 0


def test_reply_wait_is_bounded_and_ends_with_the_first_valid_reply(bus: RecordingBus, peer: AK60Peer,
                                                                   intruder: can.BusABC) -> None:
    config = AK60Config(reply_timeout_s=0.05, special_reply_timeout_s=2.0, reply_wait_s=0.0003)
    motor = AK60Motor(bus, config, clock=ManualClock())
    enabled_and_muted(motor, peer)
    bus.clear()
    assert motor.command_torque(0.0) is None
    assert bus.reads == pytest.approx([0.0003])  # the clock stands still: one read, the whole allowance
    bus.clear()
    intruder.send(reply_frame(1.0))
    for _ in range(3):
        intruder.send(reply_frame(2.0, arbitration_id=0x123))
    state = motor.command_torque(0.0)
    assert state is not None
    assert state.position_rad == pytest.approx(1.0, abs=position_resolution_rad(LIMITS))
    # A valid reply ends the waiting: the frames behind it are taken without waiting for more.
    assert bus.reads == pytest.approx([0.0003, 0.0, 0.0, 0.0, 0.0])


def test_a_refused_read_is_no_reply_in_the_cycle(bus: RecordingBus, peer: AK60Peer) -> None:
    motor = AK60Motor(bus, FAST)
    enabled_and_muted(motor, peer)
    bus.fail_reads = 1
    assert motor.command_torque(0.5) is None
    assert motor.counters.receive_errors == 1 and motor.last_receive_error is not None
    assert "Network is down" in motor.last_receive_error
    assert motor.command_torque(0.5) is None
    assert motor.last_receive_error is None and motor.unanswered_commands == 2


def test_enable_reports_a_refused_read(bus: RecordingBus, peer: AK60Peer) -> None:
    motor = AK60Motor(bus, FAST)
    bus.fail_reads = 1
    with pytest.raises(HardwareError, match="receive failed"):
        motor.enable()
    assert not motor.enabled


# --- only the motor's replies -------------------------------------------------------------------------
FOREIGN = {
    "another node, our id in byte 0": reply_frame(3.0, arbitration_id=0x123),
    "the motor's own id as sender": reply_frame(3.0, arbitration_id=MOTOR_ID),
    "another motor's reply": reply_frame(3.0, motor_id=7),
    "extended id": can.Message(arbitration_id=REPLY_ID, data=reply_frame(3.0).data, is_extended_id=True),
    "remote frame": can.Message(arbitration_id=REPLY_ID, is_remote_frame=True, dlc=8, is_extended_id=False),
    "error frame": can.Message(arbitration_id=REPLY_ID, is_error_frame=True, data=reply_frame(3.0).data,
                               is_extended_id=False),
    "CAN FD frame": can.Message(arbitration_id=REPLY_ID, data=reply_frame(3.0).data, is_fd=True,
                                is_extended_id=False),
    "empty data frame": can.Message(arbitration_id=REPLY_ID, data=b"", is_extended_id=False),
}


@pytest.mark.parametrize("name", list(FOREIGN))
def test_a_foreign_frame_is_never_a_reply(bus: RecordingBus, peer: AK60Peer, intruder: can.BusABC,
                                          name: str) -> None:
    motor = AK60Motor(bus, FAST)
    enabled_and_muted(motor, peer)
    intruder.send(FOREIGN[name])
    assert motor.command_torque(0.0) is None
    assert motor.counters.foreign == 1 and motor.counters.malformed == 0
    assert motor.unanswered_commands == 1
    # Behind it, a reply of the motor is taken.
    intruder.send(FOREIGN[name])
    intruder.send(reply_frame(-2.0))
    state = motor.command_torque(0.0)
    assert state is not None
    assert state.position_rad == pytest.approx(-2.0, abs=position_resolution_rad(LIMITS))


def test_a_frame_with_our_ids_but_a_wrong_length_is_malformed_not_taken(bus: RecordingBus, peer: AK60Peer,
                                                                        intruder: can.BusABC) -> None:
    motor = AK60Motor(bus, FAST)
    enabled_and_muted(motor, peer)
    intruder.send(garbled_frame())
    assert motor.command_torque(0.0) is None  # counted, never raised
    assert motor.counters.malformed == 1 and motor.counters.foreign == 0
    assert motor.last_malformed is not None and "7" in motor.last_malformed


def test_a_malformed_frame_followed_by_a_good_one_yields_the_good_one(bus: RecordingBus, peer: AK60Peer,
                                                                      intruder: can.BusABC) -> None:
    motor = AK60Motor(bus, FAST)
    enabled_and_muted(motor, peer)
    intruder.send(garbled_frame())
    intruder.send(reply_frame(1.5, velocity_rad_s=-3.0, torque_nm=0.75))
    state = motor.command_torque(0.0)
    assert state is not None
    assert state.position_rad == pytest.approx(1.5, abs=position_resolution_rad(LIMITS))
    assert state.velocity_rad_s == pytest.approx(-3.0, abs=velocity_resolution_rad_s(LIMITS))
    assert state.torque_nm == pytest.approx(0.75, abs=torque_resolution_nm(LIMITS))
    assert motor.counters.malformed == 1 and motor.counters.replies == 2  # the enable's and this one
    assert motor.last_malformed is None  # a valid reply came after it
    assert motor.last_state == state


def test_the_newest_valid_reply_of_a_poll_wins(bus: RecordingBus, peer: AK60Peer,
                                               intruder: can.BusABC) -> None:
    motor = AK60Motor(bus, FAST)
    enabled_and_muted(motor, peer)
    for frame in (reply_frame(1.0), garbled_frame(), reply_frame(2.0), reply_frame(2.0, motor_id=3),
                  garbled_frame()):
        intruder.send(frame)
    state = motor.command_torque(0.0)
    assert state is not None
    assert state.position_rad == pytest.approx(2.0, abs=position_resolution_rad(LIMITS))
    counters = motor.counters
    assert (counters.stale_replies, counters.malformed, counters.foreign) == (1, 2, 1)
    assert motor.last_malformed is not None  # a bad frame came after the newest good one


def test_a_wrap_between_two_replies_of_one_poll_is_counted(bus: RecordingBus, peer: AK60Peer,
                                                           intruder: can.BusABC) -> None:
    motor = AK60Motor(bus, FAST)
    enabled_and_muted(motor, peer)
    intruder.send(reply_frame(0.0))
    assert motor.command_torque(0.0) is not None
    # +12 rad, then past +12.5 rad into -12 rad (one field span, 25 rad, further): both in one poll.
    intruder.send(reply_frame(12.0))
    intruder.send(reply_frame(-12.0))
    state = motor.command_torque(0.0)
    assert state is not None
    assert state.position_rad == pytest.approx(13.0, abs=2 * position_resolution_rad(LIMITS))


def test_a_flood_is_read_a_bounded_number_of_frames_per_cycle(bus: RecordingBus, peer: AK60Peer,
                                                              intruder: can.BusABC) -> None:
    motor = AK60Motor(bus, FAST)
    enabled_and_muted(motor, peer)
    flood = reply_frame(5.0, arbitration_id=0x555)  # our id in byte 0, on another CAN id
    for _ in range(10_000):
        intruder.send(flood)
    intruder.send(reply_frame(-1.0))  # the motor's reply, behind the flood
    limit = motor.config.max_frames_per_poll
    calls = -(-10_001 // limit)  # frames are taken `limit` per call: the reply comes with the last call
    bus.clear()
    for k in range(1, calls):
        assert motor.command_torque(0.0) is None
        assert len(bus.reads) == k * limit and motor.counters.foreign == k * limit
        assert motor.counters.poll_limit_hits == k
    state = motor.command_torque(0.0)
    assert state is not None
    assert state.position_rad == pytest.approx(-1.0, abs=position_resolution_rad(LIMITS))
    assert motor.counters.foreign == 10_000 and set(bus.reads) == {0.0}
    assert motor.unanswered_commands == 1  # the last call's command


def test_a_reply_on_another_id_is_taken_only_when_opted_out(bus: RecordingBus, peer: AK60Peer,
                                                            intruder: can.BusABC) -> None:
    motor = AK60Motor(bus, AK60Config(reply_timeout_s=0.05, special_reply_timeout_s=2.0,
                                      reply_arbitration_id=None))
    enabled_and_muted(motor, peer)
    intruder.send(reply_frame(4.0, arbitration_id=0x321))
    state = motor.command_torque(0.0)
    assert state is not None
    assert state.position_rad == pytest.approx(4.0, abs=position_resolution_rad(LIMITS))
    intruder.send(reply_frame(4.0, arbitration_id=0x321, motor_id=2))  # but never another motor's
    assert motor.command_torque(0.0) is None


def test_the_default_reply_id_is_the_peers(wall_plant: WallTimePlant,
                                           can_buses: tuple[can.BusABC, can.BusABC]) -> None:
    with AK60Peer(can_buses[1], wall_plant) as peer:
        assert AK60Config().reply_arbitration_id == peer.reply_arbitration_id == REPLY_ID


# --- enter, exit and zero wait past bad frames ----------------------------------------------------------
def test_enable_waits_past_bad_frames_for_the_good_one(bus: RecordingBus, peer: AK60Peer) -> None:
    motor = AK60Motor(bus, AK60Config(special_reply_timeout_s=2.0, enter_attempts=1))
    peer.precede_next_reply([garbled_frame(), reply_frame(3.0, arbitration_id=0x123)])
    state = motor.enable()
    assert motor.enabled and state.error_code == 0
    assert [frame.kind for frame in peer.received] == [ENTER]  # answered at the first attempt
    assert motor.counters.malformed == 1 and motor.counters.foreign == 1
    motor.disable()


def test_enable_works_when_the_first_enter_frame_is_lost(bus: RecordingBus, peer: AK60Peer) -> None:
    motor = AK60Motor(bus, AK60Config(special_reply_timeout_s=0.5, enter_attempts=3))
    peer.ignore_next(1)  # lost on the bus; the answer to the next one comes behind a bad frame
    peer.precede_next_reply([garbled_frame()])
    assert motor.enable().error_code == 0 and motor.enabled
    assert sum(data == ENTER_MOTOR_MODE for data, _, _ in bus.sends) >= 2
    assert motor.counters.malformed == 1
    motor.disable()


def test_enable_times_out_on_bad_frames_only_and_says_so(bus: RecordingBus, peer: AK60Peer) -> None:
    # The driver's time passes only once it has read a bad reply: its wait ends after that, however
    # slow the machine.
    motor: AK60Motor

    def clock() -> float:
        return 1.0 if motor.counters.malformed else 0.0

    motor = AK60Motor(bus, AK60Config(special_reply_timeout_s=0.5, enter_attempts=1), clock=clock)
    peer.garble_replies(True)
    with pytest.raises(DeviceTimeoutError, match="did not decode"):
        motor.enable()
    assert motor.counters.malformed >= 1 and not motor.enabled


def test_disable_waits_past_a_bad_frame_for_the_exit_reply(bus: RecordingBus, peer: AK60Peer) -> None:
    motor = AK60Motor(bus, FAST)
    motor.enable()
    replies = motor.counters.replies
    peer.precede_next_reply([garbled_frame()])
    motor.disable()
    assert not motor.enabled
    assert motor.counters.malformed == 1 and motor.counters.replies == replies + 1


def test_set_zero_waits_past_a_bad_frame(bus: RecordingBus, peer: AK60Peer) -> None:
    motor = AK60Motor(bus, FAST)
    motor.enable()
    peer.precede_next_reply([garbled_frame()])
    motor.set_zero()
    assert motor.counters.malformed == 1 and motor.last_state is not None
    motor.disable()


# --- leaving the with block ---------------------------------------------------------------------------
def test_leaving_on_a_dead_bus_never_raises(bus: RecordingBus, peer: AK60Peer) -> None:
    with AK60Motor(bus, FAST) as motor:
        motor.enable()
        bus.fail_sends = 1000
    assert motor.exit_error is not None
    assert motor.exit_error.startswith("could not leave motor mode")
    assert "no buffer space" in motor.exit_error and "exit motor mode" in motor.exit_error
    assert motor.enabled  # truthfully: the motor was never told


def test_leaving_on_a_dead_bus_keeps_the_blocks_own_exception(bus: RecordingBus, peer: AK60Peer) -> None:
    with pytest.raises(RuntimeError, match="boom"), AK60Motor(bus, FAST) as motor:
        motor.enable()
        bus.fail_sends = 1000
        raise RuntimeError("boom")
    assert motor.exit_error is not None


def test_the_exit_frame_goes_out_even_when_the_zero_command_fails(bus: RecordingBus, peer: AK60Peer) -> None:
    with AK60Motor(bus, FAST) as motor:
        motor.enable()
        bus.fail_sends = 1  # the zero command's single attempt
    assert not motor.enabled
    assert bus.sends[-1] == (EXIT_MOTOR_MODE, FAST.reply_timeout_s, True)
    assert motor.exit_error is not None and motor.exit_error.startswith("left motor mode")
    deadline = time.monotonic() + 5.0
    while peer.in_motor_mode and time.monotonic() < deadline:
        time.sleep(0.005)
    assert not peer.in_motor_mode and peer.received[-1].kind == EXIT
