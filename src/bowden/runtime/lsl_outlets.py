"""Lab Streaming Layer outlets of a running trial: bowden's markers and the loop's signals.

``bowden run --lsl`` opens two outlets (the ``lsl`` extra: pylsl, whose wheels ship liblsl):

``bowden markers`` (type ``Markers``, source id ``bowden-markers-<host>``)
    irregular JSON strings (:func:`bowden.runtime.sync_events.marker_text`): session, trial start and
    end, repetition onsets, safe stop;
``bowden loop`` (type ``Control``, source id ``bowden-loop-<host>``)
    one double sample per control cycle: :data:`LOOP_CHANNELS`, at the loop rate.

The source ids are stable across runs on one host, so LabRecorder picks the streams up again after a
restart. Time stamps are host times (the monotonic clock of the loop, which is LSL's ``local_clock``
on Linux; the offset between the two is measured once anyway). The loop only appends to a queue; a
thread pushes to liblsl, so a slow network never delays a cycle. Discovery stays on the machine
when the environment's ``LSLAPICFG`` names a config with ``ResolveScope = machine`` (tests, examples).
"""

from __future__ import annotations

import math
import queue
import socket
import threading
import time
from collections.abc import Sequence
from typing import Any, Final

from bowden.errors import MissingExtraError

LOOP_CHANNELS: Final = (
    ("time_s", "s"),
    ("reference_elevation_rad", "rad"),
    ("elevation_rad", "rad"),
    ("desired_tension_n", "N"),
    ("commanded_torque_nm", "Nm"),
    ("tension_n", "N"),
)
# Indices of LOOP_CHANNELS in a runtime Row (bowden.contracts.TRIAL_COLUMNS order).
LOOP_ROW_INDICES: Final = (0, 1, 2, 4, 6, 9)
_STOP: Final = object()


def _pylsl() -> Any:
    try:
        import pylsl
    except ImportError:
        raise MissingExtraError(
            "publishing to Lab Streaming Layer needs the lsl extra (pylsl missing): pip install 'bowden[lsl]'"
        ) from None
    return pylsl


def _monotonic_to_lsl(pylsl: Any) -> float:
    """``local_clock() - time.monotonic()``, from the tightest of a few bracketed readings, s."""
    best = (math.inf, 0.0)
    for _ in range(5):
        before = time.monotonic()
        lsl = pylsl.local_clock()
        after = time.monotonic()
        best = min(best, (after - before, lsl - 0.5 * (before + after)))
    return best[1]


class LslOutlets:
    """The two outlets and the thread that feeds them; ``close()`` sends what is queued, then closes.

    Parameters
    ----------
    rate_hz
        Loop rate (the data stream's nominal rate).
    host
        Part of the stable source ids (default: this machine's name).
    """

    def __init__(self, *, rate_hz: float, host: str | None = None) -> None:
        pylsl = _pylsl()
        host = host or socket.gethostname()
        self.marker_source_id = f"bowden-markers-{host}"
        self.loop_source_id = f"bowden-loop-{host}"
        markers = pylsl.StreamInfo(
            "bowden markers", "Markers", 1, pylsl.IRREGULAR_RATE, pylsl.cf_string, self.marker_source_id
        )
        loop = pylsl.StreamInfo(
            "bowden loop", "Control", len(LOOP_CHANNELS), rate_hz, pylsl.cf_double64, self.loop_source_id
        )
        channels = loop.desc().append_child("channels")
        for label, unit in LOOP_CHANNELS:
            channel = channels.append_child("channel")
            channel.append_child_value("label", label)
            channel.append_child_value("unit", unit)
        self._markers = pylsl.StreamOutlet(markers)
        # Chunks of 10 samples keep the network load low at 500 Hz; latency stays 20 ms.
        self._loop = pylsl.StreamOutlet(loop, chunk_size=10, max_buffered=360)
        self.offset_s = _monotonic_to_lsl(pylsl)
        self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self.pushed_samples = 0
        self.pushed_markers = 0
        self._thread = threading.Thread(target=self._drain, name="lsl", daemon=True)
        self._thread.start()

    # --- loop side: never blocks -------------------------------------------------------------------
    def sample(self, values: Sequence[float], host_time_s: float) -> None:
        """Queue one loop sample stamped with its host time (monotonic clock), s."""
        self._queue.put((host_time_s, values))

    def marker(self, text: str, host_time_s: float) -> None:
        self._queue.put((host_time_s, text))

    # --- lifecycle --------------------------------------------------------------------------------
    def wait_for_consumers(self, timeout_s: float) -> bool:
        """Whether an inlet (LabRecorder, a test) is connected to both outlets within ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        for outlet in (self._markers, self._loop):
            if not outlet.wait_for_consumers(max(0.0, deadline - time.monotonic())):
                return False
        return True

    def close(self, *, linger_s: float = 0.5) -> None:
        """Push what is queued, give connected inlets ``linger_s`` to take it, close the outlets."""
        self._queue.put(_STOP)
        self._thread.join()
        if self._markers.have_consumers() or self._loop.have_consumers():
            time.sleep(linger_s)
        del self._markers, self._loop  # liblsl closes an outlet when its last reference goes

    def _drain(self) -> None:
        offset = self.offset_s
        while True:
            item = self._queue.get()
            if item is _STOP:
                return
            stamp, payload = item
            if isinstance(payload, str):
                self._markers.push_sample([payload], stamp + offset)
                self.pushed_markers += 1
            else:
                # Sent in chunks while the loop runs; the last sample of a burst goes out at once.
                self._loop.push_sample(list(payload), stamp + offset, self._queue.empty())
                self.pushed_samples += 1
