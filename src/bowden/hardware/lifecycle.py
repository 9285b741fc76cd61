"""Lifecycle pieces shared by the device drivers and their simulated peers.

Each driver and peer owns one background thread (polling an ADC, receiving OSC, answering CAN frames)
and is used as ``with device: ...``. These two helpers hold that logic once.
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from collections.abc import Callable
from types import TracebackType
from typing import Self


class StartedInWith(ABC):
    """``with obj:`` calls ``obj.start()`` on the way in and ``obj.close()`` on the way out."""

    @abstractmethod
    def start(self) -> Self:
        """Open the device or socket and start its thread; return ``self``."""

    @abstractmethod
    def close(self) -> None:
        """Stop the thread and release what ``start`` took."""

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


class StoppableThread:
    """One named daemon thread that runs ``target`` until :meth:`stop`; it can be started again.

    ``target`` loops while ``stop_requested`` is not set, and waits on it (``stop_requested.wait(s)``)
    instead of sleeping, so that a stop is seen at once.
    """

    def __init__(self, target: Callable[[], None], name: str, *, join_timeout_s: float = 2.0) -> None:
        self._target = target
        self._name = name
        self._join_timeout_s = join_timeout_s
        self.stop_requested = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def running(self) -> bool:
        """Started and not stopped."""
        return self._thread is not None

    def start(self) -> None:
        """Start the thread unless it already runs."""
        if self._thread is None:
            self.stop_requested.clear()
            self._thread = threading.Thread(target=self._target, name=self._name, daemon=True)
            self._thread.start()

    def stop(self) -> None:
        """Ask the target to return and wait for it (at most ``join_timeout_s``)."""
        self.stop_requested.set()
        if self._thread is not None:
            self._thread.join(timeout=self._join_timeout_s)
            self._thread = None
