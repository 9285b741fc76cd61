"""``bowden_loopback``: a python-can bus across processes over Unix datagram sockets.

This kernel has no ``vcan``, python-can's ``virtual`` bus stays inside one process, and its
``udp_multicast`` bus could leave the machine. This bus is a directory (the channel): every bus
instance binds its own socket file in it, and a frame sent on one is delivered to every other
member, as on a CAN bus (a sniffer opened on the same channel sees both directions, like candump).
Unix sockets never leave the machine.

Semantics kept from a real bus: a frame sent with no other node on the bus fails with errno 105
("No buffer space available"), which is what socketcan reports when nothing acknowledges; a member
that left is dropped; a member whose receive queue is full misses the frame (counted), it never
blocks the sender. Frames carry id, flags and up to 8 data bytes; the receive time stamp is
``time.time()`` as python-can's interfaces set it. One difference: there is no arbitration, so the
frames of one sender arrive in the order sent, but frames of two senders may reach a third node (a
sniffer) in either order when they are sent at the same moment.

Registered as the python-can interface ``bowden_loopback`` (entry point ``can.interface``), so
``can.Bus(interface="bowden_loopback", channel=directory)`` opens it.
"""

from __future__ import annotations

import errno
import itertools
import os
import select
import socket
import struct
import time
from pathlib import Path
from typing import Any, Final

import can

ERRNO_NO_BUFFER_SPACE: Final = 105
SUFFIX: Final = ".canbus"
_FRAME = struct.Struct("!IBB8s")  # arbitration id, flags, dlc, data (zero-padded)
_EXTENDED, _REMOTE, _ERROR = 1, 2, 4
_RACY_NS: Final = 50_000_000  # a listing this soon after the directory's time stamp may miss a node
_instances = itertools.count()


def encode_frame(message: can.Message) -> bytes:
    """A frame as one datagram."""
    flags = ((_EXTENDED if message.is_extended_id else 0) | (_REMOTE if message.is_remote_frame else 0)
             | (_ERROR if message.is_error_frame else 0))
    data = bytes(message.data or b"")
    if len(data) > 8:
        raise can.CanOperationError(
            f"bowden_loopback carries classic CAN frames (≤ 8 bytes), got {len(data)}"
        )
    return _FRAME.pack(message.arbitration_id, flags, message.dlc, data)


def decode_frame(datagram: bytes, channel: str) -> can.Message | None:
    """The frame in a datagram, or None if it is not one of ours."""
    if len(datagram) != _FRAME.size:
        return None
    arbitration_id, flags, dlc, data = _FRAME.unpack(datagram)
    remote = bool(flags & _REMOTE)
    return can.Message(
        timestamp=time.time(), arbitration_id=arbitration_id, is_extended_id=bool(flags & _EXTENDED),
        is_remote_frame=remote, is_error_frame=bool(flags & _ERROR), dlc=dlc,
        data=None if remote else data[: min(dlc, 8)], channel=channel, is_rx=True,
    )


class LoopbackBus(can.BusABC):
    """One node on a loopback CAN bus.

    Parameters
    ----------
    channel
        The bus: a directory (created if missing) shared by every node of the bus.
    """

    def __init__(self, channel: str | os.PathLike[str], **kwargs: Any) -> None:
        self._directory = Path(channel)
        self._directory.mkdir(parents=True, exist_ok=True)
        self._path = self._directory / f"{os.getpid()}-{next(_instances)}{SUFFIX}"
        self._socket = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self._socket.bind(str(self._path))
        self._members: list[str] = []
        self._listing_mtime_ns = -1
        self._listing_racy = True  # taken too soon after a change to trust the time stamp
        self._departed: set[str] = set()  # socket files nobody listens on any more (a killed node)
        self.dropped_frames = 0  # frames a member missed (its queue was full)
        self.channel_info = f"bowden_loopback {self._directory}"
        super().__init__(channel=str(channel), **kwargs)

    def _refresh_members(self) -> None:
        """List the other nodes again if the directory changed since the last listing.

        A directory's modification time can be coarse (a clock tick on some file systems): a node
        that joins within the same tick as the last listing leaves it unchanged. So a listing taken
        less than ``_RACY_NS`` after the time stamp it saw is not trusted, and repeated on the next send.
        """
        mtime = os.stat(self._directory).st_mtime_ns
        if mtime == self._listing_mtime_ns and not self._listing_racy:
            return
        now = time.time_ns()
        names = os.listdir(self._directory)
        self._listing_mtime_ns = mtime
        self._listing_racy = now - mtime < _RACY_NS
        own = self._path.name
        self._members = [str(self._directory / name) for name in names
                         if name.endswith(SUFFIX) and name != own and name not in self._departed]

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Deliver ``msg`` to every other node; errno 105 when there is none (nothing acknowledges)."""
        datagram = encode_frame(msg)
        self._refresh_members()
        delivered = 0
        for member in list(self._members):
            try:
                self._socket.sendto(datagram, socket.MSG_DONTWAIT, member)
            except FileNotFoundError:
                self._members.remove(member)  # the node left the bus
                continue
            except ConnectionRefusedError:
                # Its file is still there but nobody reads it: a node that was killed. Not listed again.
                self._members.remove(member)
                self._departed.add(os.path.basename(member))
                continue
            except BlockingIOError:
                self.dropped_frames += 1
            delivered += 1
        if delivered == 0:
            raise can.CanOperationError(
                "Failed to transmit: No buffer space available (no other node on the bus)",
                error_code=ERRNO_NO_BUFFER_SPACE,
            )

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            remaining = None if deadline is None else max(0.0, deadline - time.monotonic())
            try:
                readable, _, _ = select.select([self._socket], [], [], remaining)
            except InterruptedError:
                continue
            if not readable:
                return None, False
            try:
                datagram = self._socket.recv(64, socket.MSG_DONTWAIT)
            except BlockingIOError:
                continue
            message = decode_frame(datagram, self.channel_info)
            if message is not None:
                return message, False
            if deadline is not None and time.monotonic() >= deadline:
                return None, False

    def fileno(self) -> int:
        return self._socket.fileno()

    def shutdown(self) -> None:
        """Leave the bus: close the socket and remove its file."""
        if self._is_shutdown:
            return
        super().shutdown()
        self._socket.close()
        try:
            self._path.unlink()
        except FileNotFoundError:
            pass
        except OSError as error:  # pragma: no cover - a read-only directory: nothing else to do
            if error.errno != errno.ENOENT:
                raise
