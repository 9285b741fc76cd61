"""The I²C link across two processes: transfers, errnos, a stalled or vanished server.

The server runs in another interpreter with a small register file as its bus (the load cell's own
round trip through the simulated ADC is in tests/hardware/test_i2c_link.py and test_suit_process.py).
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from bowden.errors import ParameterError
from bowden.sim.link.i2c import DEFAULT_TIMEOUT_S, RemoteSMBus

PATIENT_S = 5.0  # a client timeout no busy machine reaches, where the test is not about timing out

SERVER = r"""
import errno, sys
from bowden.sim.link.i2c import I2CServer

class Registers:
    '''Device 0x48 with 256 one-byte registers; register 0x7F refuses reads (EAGAIN), 0x7E writes (EIO).'''

    def __init__(self):
        self.memory = bytearray(range(256))

    def read_i2c_block_data(self, i2c_addr, register, length, force=None):
        if i2c_addr != 0x48:
            raise OSError(errno.EREMOTEIO, "Remote I/O error")
        if register == 0x7F:
            raise OSError(errno.EAGAIN, "busy")
        return list(self.memory[register:register + length])

    def write_i2c_block_data(self, i2c_addr, register, data, force=None):
        if i2c_addr != 0x48:
            raise OSError(errno.EREMOTEIO, "Remote I/O error")
        if register == 0x7E:
            raise OSError(errno.EIO, "I/O error")
        self.memory[register:register + len(data)] = bytes(data)

with I2CServer(Registers(), sys.argv[1]):
    print("ready", flush=True)
    sys.stdin.read()  # until the test closes our stdin
"""


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[subprocess.Popen[str], Path]]:
    """One server for the module (an interpreter importing bowden takes a second or two to start)."""
    path = tmp_path_factory.mktemp("link") / "i2c.sock"
    process = subprocess.Popen([sys.executable, "-c", SERVER, str(path)], stdin=subprocess.PIPE,
                               stdout=subprocess.PIPE, text=True)
    assert process.stdout is not None and process.stdin is not None
    try:
        assert process.stdout.readline().strip() == "ready"
        yield process, path
    finally:
        os.kill(process.pid, signal.SIGCONT)
        process.stdin.close()
        assert process.wait(timeout=30) == 0
    assert not path.exists()  # the server removed its socket file


def read_once_answered(bus: RemoteSMBus, register: int, length: int) -> list[int]:
    """Read, trying again while the (just resumed, busy) server is late; other errors are raised."""
    deadline = time.monotonic() + 30.0
    while True:
        try:
            return bus.read_i2c_block_data(0x48, register, length)
        except OSError as error:
            if error.errno != errno.ETIMEDOUT or time.monotonic() > deadline:
                raise


def stopped(pid: int) -> bool:
    return Path(f"/proc/{pid}/stat").read_text().rsplit(") ", 1)[1].split()[0] in ("T", "t")


def test_transfers_cross_the_process_boundary(server: tuple[subprocess.Popen[str], Path]) -> None:
    _, path = server
    with RemoteSMBus(path, timeout_s=PATIENT_S) as bus:
        assert bus.read_i2c_block_data(0x48, 0x10, 4) == [0x10, 0x11, 0x12, 0x13]
        bus.write_i2c_block_data(0x48, 0x20, [0xDE, 0xAD, 0xBE, 0xEF])
        assert bus.read_i2c_block_data(0x48, 0x20, 4) == [0xDE, 0xAD, 0xBE, 0xEF]
        assert bus.read_i2c_block_data(0x48, 0xFE, 2) == [0xFE, 0xFF]
    assert list(path.parent.glob("i2c-client-*")) == []  # the client removed its socket file


@pytest.mark.parametrize(("address", "register", "write", "code"), [
    (0x49, 0x00, False, errno.EREMOTEIO),  # nobody at this address
    (0x49, 0x00, True, errno.EREMOTEIO),
    (0x48, 0x7F, False, errno.EAGAIN),
    (0x48, 0x7E, True, errno.EIO),
])
def test_the_servers_errno_comes_back(server: tuple[subprocess.Popen[str], Path], address: int,
                                      register: int, write: bool, code: int) -> None:
    _, path = server
    with RemoteSMBus(path, timeout_s=PATIENT_S) as bus:
        with pytest.raises(OSError) as info:
            if write:
                bus.write_i2c_block_data(address, register, [1, 2])
            else:
                bus.read_i2c_block_data(address, register, 2)
        assert info.value.errno == code
        assert bus.read_i2c_block_data(0x48, 0x01, 1) == [0x01]  # the link is fine afterwards


def test_a_stalled_server_times_out_and_its_late_reply_is_dropped(
        server: tuple[subprocess.Popen[str], Path]) -> None:
    process, path = server
    assert DEFAULT_TIMEOUT_S == 0.020
    with RemoteSMBus(path) as bus:
        os.kill(process.pid, signal.SIGSTOP)
        deadline = time.monotonic() + 10.0
        while not stopped(process.pid):
            assert time.monotonic() < deadline, "the server did not stop"
            time.sleep(0.005)
        with pytest.raises(OSError) as info:
            bus.read_i2c_block_data(0x48, 0x30, 2)
        assert info.value.errno == errno.ETIMEDOUT
        os.kill(process.pid, signal.SIGCONT)
        # The server now answers the old request too: that reply must not pass for this one's.
        assert read_once_answered(bus, 0x40, 2) == [0x40, 0x41]
        assert read_once_answered(bus, 0x50, 1) == [0x50]


def test_a_server_that_is_gone_is_a_timeout(tmp_path: Path) -> None:
    with RemoteSMBus(tmp_path / "nobody.sock") as bus:
        with pytest.raises(OSError) as info:
            bus.read_i2c_block_data(0x48, 0, 2)
        assert info.value.errno == errno.ETIMEDOUT


def test_the_timeout_must_be_positive(tmp_path: Path) -> None:
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ParameterError, match="timeout_s"):
            RemoteSMBus(tmp_path / "i2c.sock", timeout_s=bad)
    assert list(tmp_path.iterdir()) == []
