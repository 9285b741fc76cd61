"""I²C transactions across processes: the load cell's reader in the loop's process, the ADC in the
simulated suit's.

:class:`RemoteSMBus` has the methods of ``smbus2.SMBus`` the ADS1115 driver uses; each call is one
request and one reply over a Unix datagram socket (loopback by construction) to an
:class:`I2CServer` holding the simulated bus (:class:`~bowden.sim.peers.FakeSMBus`). An ``OSError``
on the far side comes back with its errno (an address nobody answers: EREMOTEIO; an injected loose
wire: EIO); a server that does not answer in time is ``ETIMEDOUT`` — what the driver sees of an
unplugged ADC either way.
"""

from __future__ import annotations

import errno
import itertools
import os
import socket
import struct
import time
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import Final, Self

from bowden.errors import ParameterError
from bowden.hardware.ads1115 import SMBusLike
from bowden.hardware.lifecycle import StartedInWith, StoppableThread

_REQUEST = struct.Struct("!IBBBB")  # request id, op, i2c address, register, length
_REPLY = struct.Struct("!IH")  # request id, errno (0: done)
_READ, _WRITE = 0, 1
_clients = itertools.count()
# A local round trip takes ~0.1 ms; a simulated suit that has not answered in 20 ms is stalled or gone.
DEFAULT_TIMEOUT_S: Final = 0.020


class RemoteSMBus:
    """The client end: an ``smbus2.SMBus`` look-alike whose transfers happen in another process.

    Parameters
    ----------
    server_path
        The server's socket file.
    timeout_s
        A transfer without a reply within this long (s) fails with ``ETIMEDOUT`` (default 20 ms;
        the round trip takes about 0.1 ms). A reply that comes later is recognised by its request
        id and dropped.
    """

    def __init__(self, server_path: str | os.PathLike[str], *, timeout_s: float = DEFAULT_TIMEOUT_S) -> None:
        if not timeout_s > 0.0:
            raise ParameterError(f"RemoteSMBus timeout_s must be positive, got {timeout_s!r}")
        self._server = str(server_path)
        self._timeout_s = timeout_s
        self._path = Path(server_path).with_name(f"i2c-client-{os.getpid()}-{next(_clients)}.sock")
        self._socket = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self._socket.bind(str(self._path))
        self._ids = itertools.count(1)

    def _transfer(self, op: int, i2c_addr: int, register: int, length: int, payload: bytes) -> bytes:
        request_id = next(self._ids) & 0xFFFFFFFF
        request = _REQUEST.pack(request_id, op, i2c_addr & 0xFF, register & 0xFF, length & 0xFF) + payload
        try:
            self._socket.sendto(request, self._server)
        except (FileNotFoundError, ConnectionRefusedError):
            raise OSError(errno.ETIMEDOUT, "I2C transfer timed out (the simulated bus is gone)") from None
        deadline = time.monotonic() + self._timeout_s
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                raise OSError(errno.ETIMEDOUT, f"I2C transfer to {i2c_addr:#x} timed out")
            self._socket.settimeout(remaining)
            try:
                reply = self._socket.recv(512)
            except TimeoutError:
                continue
            if len(reply) < _REPLY.size:
                continue
            reply_id, code = _REPLY.unpack_from(reply)
            if reply_id != request_id:
                continue  # a late reply to an earlier, timed-out transfer
            if code:
                name = errno.errorcode.get(code, str(code))
                raise OSError(code, f"I2C transfer to {i2c_addr:#x} failed: {name}")
            return reply[_REPLY.size:]

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int,
                            force: bool | None = None) -> list[int]:
        return list(self._transfer(_READ, i2c_addr, register, length, b""))

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: Sequence[int],
                             force: bool | None = None) -> None:
        self._transfer(_WRITE, i2c_addr, register, len(data), bytes(data))

    def close(self) -> None:
        self._socket.close()
        self._path.unlink(missing_ok=True)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


class I2CServer(StartedInWith):
    """The server end: answers :class:`RemoteSMBus` transfers from ``bus`` in a background thread.

    Parameters
    ----------
    bus
        The simulated I²C bus (e.g. ``FakeSMBus(ADS1115Peer(...))``).
    path
        The socket file to listen on.
    """

    def __init__(self, bus: SMBusLike, path: str | os.PathLike[str]) -> None:
        self._bus = bus
        self.path = Path(path)
        self._socket: socket.socket | None = None
        self._thread = StoppableThread(self._serve, "i2c-server")
        self.silent = False  # an unplugged device: requests go unanswered

    def start(self) -> Self:
        if self._socket is None:
            self._socket = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
            self._socket.bind(str(self.path))
            self._socket.settimeout(0.05)
            self._thread.start()
        return self

    def close(self) -> None:
        self._thread.stop()
        if self._socket is not None:
            self._socket.close()
            self._socket = None
            self.path.unlink(missing_ok=True)

    def _serve(self) -> None:
        sock = self._socket
        assert sock is not None
        while not self._thread.stop_requested.is_set():
            try:
                request, client = sock.recvfrom(512)
            except TimeoutError:
                continue
            except OSError:
                return  # closed
            if len(request) < _REQUEST.size or self.silent:
                continue
            request_id, op, address, register, length = _REQUEST.unpack_from(request)
            data = b""
            code = 0
            try:
                if op == _READ:
                    data = bytes(self._bus.read_i2c_block_data(address, register, length))
                else:
                    self._bus.write_i2c_block_data(address, register, list(request[_REQUEST.size:]))
            except OSError as error:
                code = error.errno or errno.EIO
            try:
                sock.sendto(_REPLY.pack(request_id, code) + data, client)
            except OSError:
                continue  # the client went away
