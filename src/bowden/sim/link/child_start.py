"""Starting the simulated suit's process, and keeping the next one warming up for a process that starts
one suit after another.

A suit's process imports numba and loads the plant's compiled kernels before it can answer: about
1.7 s of CPU, 2.3 s of wall time on a slow two-core host (2026-11-28), paid by every
:meth:`~bowden.sim.link.suit_process.SimulatedSuitProcess.start`. A process that starts suits one
after another (the test suite's real-time tests: about seventy) can keep one *spare* started ahead:
it warms up while the current suit runs, then waits for its settings. :func:`take_child` hands it
out and starts the next. Off by default (:func:`keep_a_spare`): a process that starts one suit would
pay for a second.

The spare is a fresh interpreter like any other child (no fork of a process with threads), started
by this process, so its handle (exit code, stderr) is the same. If this process goes away first,
the spare reads end-of-file where it waits for its settings and ends by itself.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import socket
import subprocess
import sys
import threading
from dataclasses import dataclass
from multiprocessing.connection import Connection

CHILD_MODULE = "bowden.sim.link.suit_process"


@dataclass
class StartedChild:
    """A child process and the parent's ends of its two socket pairs."""

    process: subprocess.Popen[str]
    requests: Connection  # requests and their replies
    notices: Connection  # one-way notices from the loop

    def discard(self) -> None:
        """End a child that was never given its settings (it has nothing to stop) and reap it."""
        self.requests.close()
        self.notices.close()
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait(timeout=10.0)
        if self.process.stderr is not None:
            self.process.stderr.close()


def start_child() -> StartedChild:
    """A fresh interpreter (not a fork of this one with its threads and sockets, and not
    multiprocessing's spawn, which would re-run the caller's main script) running the suit's child,
    talking over two socket pairs."""
    parent_requests, child_requests = socket.socketpair()
    notice_writer, notice_reader = socket.socketpair()
    fds = (child_requests.fileno(), notice_reader.fileno())
    try:
        process = subprocess.Popen(
            [sys.executable, "-m", CHILD_MODULE, str(fds[0]), str(fds[1]), str(os.getpid())],
            pass_fds=fds, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
            text=True,
        )
    except BaseException:
        for end in (parent_requests, notice_writer):
            end.close()
        raise
    finally:
        child_requests.close()
        notice_reader.close()
    return StartedChild(process, Connection(parent_requests.detach()), Connection(notice_writer.detach()))


class _Spare:
    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._wanted = False
        self._child: StartedChild | None = None
        self._owner_pid = os.getpid()

    def want(self, wanted: bool) -> bool:
        with self._lock:
            before, self._wanted = self._wanted, wanted
            child, self._child = (self._child, None) if not wanted else (None, self._child)
        if child is not None:
            child.discard()
        return before

    def take(self) -> StartedChild:
        with self._lock:
            child, self._child = self._child, None
            if os.getpid() != self._owner_pid:  # a forked copy of this process: the spare is not ours
                self._owner_pid, child, self._wanted = os.getpid(), None, False
            if child is not None and child.process.poll() is not None:
                child.discard()  # it died waiting: start another
                child = None
            if child is None:
                child = start_child()
            if self._wanted:
                self._child = start_child()
        return child

    def pid(self) -> int | None:
        with self._lock:
            return self._child.process.pid if self._child is not None else None

    def discard(self) -> None:
        with self._lock, contextlib.suppress(OSError, ValueError):
            if self._child is not None and os.getpid() == self._owner_pid:
                self._child.discard()
            self._child = None


_SPARE = _Spare()
atexit.register(_SPARE.discard)


def keep_a_spare(wanted: bool = True) -> bool:
    """Keep one suit's process started ahead of the next :func:`take_child` (off: the spare ends);
    returns the setting before."""
    return _SPARE.want(wanted)


def spare_pid() -> int | None:
    """The spare's process id, if one is waiting."""
    return _SPARE.pid()


def take_child() -> StartedChild:
    """The spare if there is one (else a new child), and a new spare if wanted."""
    return _SPARE.take()
