"""SIGINT/SIGTERM → a safe stop of the control loop or the bench run.

The handler only sets the stop request (one attribute write, safe in a signal handler); the loop sees
it at the top of its next cycle and starts the safe-state ramp, so the stop begins within one cycle.
It is never an exception raised wherever the signal lands: that could leave a driver's lock held (a
bench run then hung at its exit) or cut the safe stop itself short. The handler replaces whatever
the process inherited: a script's background job ignores SIGINT (POSIX), and SIGTERM's default would
end the process without its safe stop. Handlers can only be installed from the main thread;
elsewhere this does nothing and says so.
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
