"""The ``bowden_loopback`` CAN bus: frames cross processes bit-exactly and never leave the machine."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import can
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bowden.sim.link.can_bus import (
    ERRNO_NO_BUFFER_SPACE,
    SUFFIX,
    LoopbackBus,
    accepts,
    decode_filters,
    encode_filters,
)

FRAMES = [
    can.Message(arbitration_id=0x001, data=bytes([0xFF] * 7 + [0xFC]), is_extended_id=False),
    can.Message(arbitration_id=0x000, data=bytes([1, 2, 3, 4, 5, 6]), is_extended_id=False),
    can.Message(arbitration_id=0x1ABCDE0F, data=b"\x00", is_extended_id=True),
    can.Message(arbitration_id=0x123, is_remote_frame=True, dlc=4, is_extended_id=False),
    can.Message(arbitration_id=0x0, is_error_frame=True, data=b"", is_extended_id=False),
]

ECHO = """
import sys, can
bus = can.Bus(interface="bowden_loopback", channel=sys.argv[1])
print("ready", flush=True)
for _ in range(int(sys.argv[2])):
    message = bus.recv(timeout=10.0)
    reply = can.Message(arbitration_id=message.arbitration_id ^ 0x7,
                        data=bytes(b ^ 0xFF for b in message.data),
                        is_extended_id=message.is_extended_id, is_remote_frame=message.is_remote_frame,
                        is_error_frame=message.is_error_frame, dlc=message.dlc)
    bus.send(reply)
bus.shutdown()
"""


def same_frame(a: can.Message, b: can.Message) -> bool:
    return (a.arbitration_id, a.is_extended_id, a.is_remote_frame, a.is_error_frame, a.dlc,
            bytes(a.data)) == (b.arbitration_id, b.is_extended_id, b.is_remote_frame, b.is_error_frame,
                               b.dlc, bytes(b.data))


def test_frames_cross_processes_bit_exactly_and_a_sniffer_sees_both_ways(tmp_path: Path) -> None:
    channel = str(tmp_path / "bus")
    with can.Bus(interface="bowden_loopback", channel=channel) as bus, \
            can.Bus(interface="bowden_loopback", channel=channel) as sniffer:
        echo = subprocess.Popen([sys.executable, "-c", ECHO, channel, str(len(FRAMES))],
                                stdout=subprocess.PIPE, text=True)
        try:
            assert echo.stdout is not None and echo.stdout.readline().strip() == "ready"
            for frame in FRAMES:
                bus.send(frame)
                reply = bus.recv(timeout=10.0)
                assert reply is not None
                expected = can.Message(arbitration_id=frame.arbitration_id ^ 0x7,
                                       data=bytes(b ^ 0xFF for b in frame.data),
                                       is_extended_id=frame.is_extended_id,
                                       is_remote_frame=frame.is_remote_frame,
                                       is_error_frame=frame.is_error_frame, dlc=frame.dlc)
                assert same_frame(reply, expected), (reply, expected)
                seen = [sniffer.recv(timeout=5.0), sniffer.recv(timeout=5.0)]
                assert all(m is not None for m in seen)
                # Without arbitration, frames of two senders may reach a third node in either order.
                if not same_frame(seen[0], frame):  # type: ignore[arg-type]
                    seen.reverse()
                assert same_frame(seen[0], frame) and same_frame(seen[1], expected)  # type: ignore[arg-type]
        finally:
            assert echo.wait(timeout=30) == 0
    assert list(Path(channel).iterdir()) == []  # every node removed its socket file


def test_a_send_with_nobody_on_the_bus_fails_like_socketcan(tmp_path: Path) -> None:
    with LoopbackBus(tmp_path / "bus") as alone:
        with pytest.raises(can.CanOperationError, match="No buffer space") as info:
            alone.send(FRAMES[0])
        assert info.value.error_code == ERRNO_NO_BUFFER_SPACE
        with LoopbackBus(tmp_path / "bus") as other:
            alone.send(FRAMES[0])
            assert other.recv(timeout=5.0) is not None
        # The other node left: nothing acknowledges any more.
        with pytest.raises(can.CanOperationError):
            alone.send(FRAMES[0])


def test_recv_times_out_with_none(tmp_path: Path) -> None:
    with LoopbackBus(tmp_path / "bus") as bus:
        assert bus.recv(timeout=0.0) is None
        assert bus.recv(timeout=0.01) is None


def test_the_interface_is_registered_with_python_can() -> None:
    assert "bowden_loopback" in can.interfaces.VALID_INTERFACES


def test_a_node_joining_within_the_directorys_time_stamp_tick_is_heard(tmp_path: Path) -> None:
    # File systems with coarse time stamps can leave the directory's mtime unchanged when a node
    # joins right after a listing; setting the mtime back by hand makes that case certain.
    directory = tmp_path / "bus"
    with LoopbackBus(directory) as sender, LoopbackBus(directory) as first:
        stamp = os.stat(directory).st_mtime_ns
        sender.send(FRAMES[0])
        assert first.recv(timeout=5.0) is not None
        with LoopbackBus(directory) as late:
            os.utime(directory, ns=(stamp, stamp))  # the join did not change the time stamp
            sender.send(FRAMES[1])
            assert late.recv(timeout=5.0) is not None
            assert first.recv(timeout=5.0) is not None


def test_a_killed_node_is_dropped_and_not_listed_again(tmp_path: Path) -> None:
    directory = tmp_path / "bus"
    directory.mkdir()
    # A node that was killed: its socket file is left behind, nobody reads it.
    dead = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    dead.bind(str(directory / f"999999-0{SUFFIX}"))
    dead.close()
    with LoopbackBus(directory) as alone:
        with pytest.raises(can.CanOperationError) as info:
            alone.send(FRAMES[0])
        assert info.value.error_code == ERRNO_NO_BUFFER_SPACE
        with LoopbackBus(directory) as other:  # the listing is renewed: the dead file stays out
            alone.send(FRAMES[0])
            assert same_frame(other.recv(timeout=5.0), FRAMES[0])  # type: ignore[arg-type]


def test_frames_longer_than_classic_can_are_refused(tmp_path: Path) -> None:
    with LoopbackBus(tmp_path / "bus") as bus, LoopbackBus(tmp_path / "bus"), \
            pytest.raises(can.CanOperationError, match="8 bytes"):
        bus.send(can.Message(arbitration_id=1, data=bytes(12), is_fd=True))


MOTOR_2 = [{"can_id": 2, "can_mask": 0x7FF, "extended": False}]


def test_a_node_with_acceptance_filters_hears_only_what_they_accept(tmp_path: Path) -> None:
    # The simulated motors' nodes (sim/link/suit_process.py): the senders apply a node's filters, so
    # it is not woken for frames it would drop; a sniffer without filters still hears everything.
    directory = tmp_path / "bus"
    with LoopbackBus(directory) as sender, LoopbackBus(directory, can_filters=MOTOR_2) as motor, \
            LoopbackBus(directory) as sniffer:
        frames = [can.Message(arbitration_id=i, data=bytes([i]), is_extended_id=extended)
                  for i, extended in ((1, False), (2, True), (2, False), (3, False))]
        for frame in frames:
            sender.send(frame)
        heard = motor.recv(timeout=5.0)
        assert heard is not None and same_frame(heard, frames[2])
        assert motor.recv(timeout=0.05) is None  # nothing else reached its socket
        assert all(same_frame(sniffer.recv(timeout=5.0), frame) for frame in frames)  # type: ignore[arg-type]


def test_a_frame_no_filter_accepts_is_still_acknowledged(tmp_path: Path) -> None:
    # On a real bus every controller acknowledges a frame, whatever its filters keep: no errno 105.
    with LoopbackBus(tmp_path / "bus") as sender, LoopbackBus(tmp_path / "bus", can_filters=MOTOR_2) as motor:
        sender.send(FRAMES[0])  # id 1
        assert motor.recv(timeout=0.05) is None


def test_filters_are_fixed_while_the_node_is_open(tmp_path: Path) -> None:
    with LoopbackBus(tmp_path / "bus", can_filters=MOTOR_2) as motor:
        motor.set_filters(MOTOR_2)  # the same: nothing changes
        with pytest.raises(can.CanOperationError, match="given when the bus is opened"):
            motor.set_filters(None)
        assert motor.filters == MOTOR_2


@given(can_id=st.integers(0, 0x1FFFFFFF), can_mask=st.integers(0, 0x1FFFFFFF),
       extended=st.sampled_from([None, False, True]), arbitration_id=st.integers(0, 0x1FFFFFFF),
       is_extended=st.booleans())
def test_the_senders_apply_python_can_s_own_filter_rule(can_id: int, can_mask: int, extended: bool | None,
                                                         arbitration_id: int, is_extended: bool) -> None:
    entry: dict[str, object] = {"can_id": can_id, "can_mask": can_mask}
    if extended is not None:
        entry["extended"] = extended
    if not is_extended:
        arbitration_id &= 0x7FF
    message = can.Message(arbitration_id=arbitration_id, is_extended_id=is_extended)
    with can.Bus(interface="virtual", channel="filter-rule", can_filters=[entry]) as reference:
        expected = reference._matches_filters(message)
    name = f"1-0{encode_filters([entry])}{SUFFIX}"  # type: ignore[list-item]
    assert accepts(decode_filters(name), message) == expected
