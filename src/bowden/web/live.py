"""Live data from the control loop to the browsers: a non-blocking tap and a WebSocket fan-out.

The control loop runs in its own thread and must never wait for the web server. Its record
callback therefore only appends ``(wall stamp, sequence number, row)`` to a bounded deque (an
atomic C operation) and, if the server has not yet been told, schedules one wake-up on the event
loop (``call_soon_threadsafe``, at most once per batch). The server drains the deque, thins the
rows to the display rate and sends one message per batch to every connected browser.

Each browser has its own bounded queue; a slow browser loses its oldest messages instead of
slowing the others or the server (a display that fell behind only needs the newest samples).
The wall stamp (``time.time()`` when the loop handed the row over) travels with each sample, so
the page can report when the sample reached its pixels (``benchmarks/web_latency.py``).
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import json
import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Final

_log = logging.getLogger(__name__)

ROLE_DISPLAY: Final = "display"
ROLE_CONSOLE: Final = "console"
ROLES: Final = (ROLE_DISPLAY, ROLE_CONSOLE)
TAP_CAPACITY: Final = 20_000  # rows kept if the server stalls (40 s at 500 Hz); older ones are dropped
CLIENT_QUEUE_MESSAGES: Final = 256

Stamped = tuple[float, int, tuple[float | int, ...]]


class SampleTap:
    """Thread-to-event-loop bridge for the loop's rows.

    Parameters
    ----------
    loop
        The server's event loop.
    wake
        Called in the event loop when rows are waiting (once per batch).
    """

    def __init__(self, loop: asyncio.AbstractEventLoop, wake: Callable[[], None]) -> None:
        self._rows: collections.deque[Stamped] = collections.deque(maxlen=TAP_CAPACITY)
        self.loop = loop
        self._wake = wake
        self._pending = False
        self._sequence = 0

    def record(self, row: tuple[float | int, ...]) -> None:
        """Loop side: keep the row with its wall stamp; never blocks, never raises."""
        self._rows.append((time.time(), self._sequence, row))
        self._sequence += 1
        if not self._pending:
            self._pending = True
            # RuntimeError: the server is shutting down; the control loop must go on regardless.
            with contextlib.suppress(RuntimeError):
                self.loop.call_soon_threadsafe(self._wake)

    def drain(self) -> list[Stamped]:
        """Event-loop side: everything recorded since the last drain, oldest first."""
        # Clear the flag before draining: a row appended meanwhile is either drained now or wakes
        # the server again, never stranded.
        self._pending = False
        rows = self._rows
        out = []
        while rows:
            out.append(rows.popleft())
        return out


@dataclass(eq=False)  # identity, so clients can live in a set
class _Client:
    role: str
    queue: asyncio.Queue[str] = field(default_factory=lambda: asyncio.Queue(CLIENT_QUEUE_MESSAGES))
    dropped: int = 0


class LiveHub:
    """The connected browsers and what each role receives."""

    def __init__(self) -> None:
        self._clients: set[_Client] = set()

    def connect(self, role: str) -> _Client:
        """Register a browser of ``role``; its messages arrive in the returned client's queue."""
        if role not in ROLES:
            raise ValueError(f"unknown role {role!r}")
        client = _Client(role)
        self._clients.add(client)
        return client

    def disconnect(self, client: _Client) -> None:
        self._clients.discard(client)

    def count(self, role: str | None = None) -> int:
        """Connected browsers (of one role)."""
        return sum(1 for c in self._clients if role is None or c.role == role)

    def pending(self) -> int:
        """Messages queued and not yet taken by the browsers' senders (safe to poll from any thread)."""
        return sum(client.queue.qsize() for client in list(self._clients))

    def publish(self, message: Mapping[str, object], roles: Sequence[str] = ROLES) -> None:
        """Queue ``message`` (JSON-encoded once) for every browser of ``roles``."""
        targets = [c for c in self._clients if c.role in roles]
        if not targets:
            return
        text = encode(message)
        for client in targets:
            send(client, text)


def send(client: _Client, text: str) -> None:
    """Queue one message for one browser, dropping its oldest message if its queue is full."""
    queue = client.queue
    if queue.full():
        queue.get_nowait()
        client.dropped += 1
    queue.put_nowait(text)


def encode(message: Mapping[str, object]) -> str:
    """JSON with NaN and infinities as null (JavaScript's JSON.parse refuses NaN)."""
    return json.dumps(_finite(message), separators=(",", ":"), allow_nan=False)


def _finite(value: object) -> object:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


class Thinning:
    """Keeps the first row of each ``1/rate_hz`` slot of loop time (the display needs ≤ 100 Hz).

    Slots rather than "at least a period since the last kept row": at a loop rate that is not a
    multiple of the display rate (250 Hz for 100 Hz) the latter would keep every third row (83 Hz).

    Parameters
    ----------
    rate_hz
        Highest rate of the rows kept.
    """

    def __init__(self, rate_hz: float) -> None:
        self.period_s = 1.0 / rate_hz
        self._last_slot = -math.inf

    def reset(self) -> None:
        self._last_slot = -math.inf

    def keep(self, rows: list[Stamped], time_index: int = 0) -> list[Stamped]:
        out = []
        period = self.period_s
        for stamped in rows:
            # The 1e-6 slot tolerance keeps t = 0.01 (0.00999… in binary) in the slot it names.
            slot = math.floor(float(stamped[2][time_index]) / period + 1e-6)
            if slot > self._last_slot:
                out.append(stamped)
                self._last_slot = slot
        return out
