"""SIGINT/SIGTERM → a safe stop of the control loop.

The handler only sets the loop's stop request (one attribute write, safe in a signal handler); the
loop sees it at the top of its next cycle and starts the safe-state ramp, so the stop begins within
one cycle. Handlers can only be installed from the main thread; elsewhere this does nothing and says so.
"""

from __future__ import annotations

import logging
import signal
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from types import FrameType

_log = logging.getLogger(__name__)


@contextmanager
def stop_on_signals(
    request_stop: Callable[[str], None],
    signals: Sequence[signal.Signals] = (signal.SIGINT, signal.SIGTERM),
) -> Iterator[None]:
    """Within the block, each of ``signals`` calls ``request_stop("signal NAME")``; restored after."""
    if threading.current_thread() is not threading.main_thread():
        _log.warning("signal handlers can only be installed from the main thread; not installed")
        yield
        return

    def handler(signum: int, frame: FrameType | None) -> None:
        request_stop(f"signal {signal.Signals(signum).name}")

    previous = {sig: signal.signal(sig, handler) for sig in signals}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


@contextmanager
def interrupt_on_signals(
    signals: Sequence[signal.Signals] = (signal.SIGINT, signal.SIGTERM),
) -> Iterator[None]:
    """Within the block, each of ``signals`` raises KeyboardInterrupt in the main thread (Python's own
    Ctrl-C), whatever the process inherited: a command started in the background by a script ignores
    SIGINT (POSIX), and SIGTERM would end it without its safe stop. For code whose safe stop is a
    ``KeyboardInterrupt`` handler (the bench run); restored after."""
    if threading.current_thread() is not threading.main_thread():
        _log.warning("signal handlers can only be installed from the main thread; not installed")
        yield
        return
    previous = {sig: signal.signal(sig, signal.default_int_handler) for sig in signals}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
