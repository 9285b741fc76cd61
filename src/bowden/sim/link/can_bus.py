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

Acceptance filters given when a node opens (``can_filters``, python-can's rule) are applied by the
senders, as a CAN controller's filters are applied before the host is woken: the filters are part of
the node's socket file name, and a frame no filter of a node accepts is not sent to it (it still
counts as acknowledged, as on a real bus). A simulated motor then wakes only for its own frames
(the bench's two motors each woke for every frame on the bus, two of three not theirs).

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
_FILTERS_MARK: Final = "~"  # in a socket file's name: the acceptance filters follow
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


Filter = tuple[int, int, bool | None]  # can_id, can_mask, extended (None: either)
_KIND = {None: "a", False: "s", True: "x"}


def encode_filters(filters: can.typechecking.CanFilters | None) -> str:
    """Acceptance filters as a part of a file name ("" for none: every frame)."""
    if not filters:
        return ""
    parts = []
    for entry in filters:
        extended = entry.get("extended")
        parts.append(f"{int(entry['can_id']):x}.{int(entry['can_mask']):x}.{_KIND[extended]}")
    return _FILTERS_MARK + "+".join(parts)


def decode_filters(name: str) -> tuple[Filter, ...] | None:
    """The filters a socket file's name carries (None: it takes every frame)."""
    stem = name.removesuffix(SUFFIX)
    if _FILTERS_MARK not in stem:
        return None
    kinds = {code: extended for extended, code in _KIND.items()}
    decoded = []
    try:
        for part in stem.split(_FILTERS_MARK, 1)[1].split("+"):
            can_id, can_mask, kind = part.split(".")
            decoded.append((int(can_id, 16), int(can_mask, 16), kinds[kind]))
    except (ValueError, KeyError):
        return None  # not a name this module made: send it every frame
    return tuple(decoded)


def accepts(filters: tuple[Filter, ...] | None, message: can.Message) -> bool:
    """python-can's filter rule (``BusABC._matches_filters``): some filter's extended flag (if
    given) and masked id match."""
    if filters is None:
        return True
    return any((extended is None or extended == message.is_extended_id)
               and (can_id ^ message.arbitration_id) & can_mask == 0
               for can_id, can_mask, extended in filters)


class LoopbackBus(can.BusABC):
    """One node on a loopback CAN bus.

    Parameters
    ----------
    channel
        The bus: a directory (created if missing) shared by every node of the bus.
    can_filters
        Acceptance filters (python-can's), applied by the senders; fixed while the node is open.
    """

    def __init__(self, channel: str | os.PathLike[str],
                 can_filters: can.typechecking.CanFilters | None = None, **kwargs: Any) -> None:
        self._directory = Path(channel)
        self._directory.mkdir(parents=True, exist_ok=True)
        self._opened_filters = can_filters or None
        self._published_filters = encode_filters(can_filters)
        name = f"{os.getpid()}-{next(_instances)}{self._published_filters}{SUFFIX}"
        self._path = self._directory / name
        self._socket = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self._socket.bind(str(self._path))
        self._members: list[tuple[str, tuple[Filter, ...] | None]] = []
        self._listing_mtime_ns = -1
        self._listing_racy = True  # taken too soon after a change to trust the time stamp
        self._departed: set[str] = set()  # socket files nobody listens on any more (a killed node)
        self.dropped_frames = 0  # frames a member missed (its queue was full)
        self.channel_info = f"bowden_loopback {self._directory}"
        super().__init__(channel=str(channel), can_filters=can_filters, **kwargs)

    def _apply_filters(self, filters: can.typechecking.CanFilters | None) -> None:
        """The senders apply the filters the node opened with; others cannot reach them."""
        if encode_filters(filters) != self._published_filters:
            self._filters = self._opened_filters
            raise can.CanOperationError(
                "bowden_loopback applies acceptance filters given when the bus is opened "
                "(can.Bus(..., can_filters=...)); they cannot change while it is open")

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
        self._members = [(str(self._directory / name), decode_filters(name)) for name in names
                         if name.endswith(SUFFIX) and name != own and name not in self._departed]

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Deliver ``msg`` to every other node; errno 105 when there is none (nothing acknowledges)."""
        datagram = encode_frame(msg)
        self._refresh_members()
        delivered = 0
        for member in list(self._members):
            path, filters = member
            if not accepts(filters, msg):
                delivered += 1  # its controller acknowledges the frame and drops it
                continue
            try:
                self._socket.sendto(datagram, socket.MSG_DONTWAIT, path)
            except FileNotFoundError:
                self._members.remove(member)  # the node left the bus
                continue
            except ConnectionRefusedError:
                # Its file is still there but nobody reads it: a node that was killed. Not listed again.
                self._members.remove(member)
                self._departed.add(os.path.basename(path))
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
                return message, True  # the senders applied this node's filters
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
