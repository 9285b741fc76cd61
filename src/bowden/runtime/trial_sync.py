"""A trial's sync signals: the trigger line, LSL markers and loop samples, the sync events in the store.

:class:`TrialSync` is a row sink of the control loop (like the recorder): per cycle it reads the
monotonic clock once, keeps where the loop's time zero lies on it (the smallest ``host - t`` seen:
the row is handed over right after the cycle's wake-up, so the smallest gap is the true zero plus the
shortest cycle's work, microseconds) and queues the row for LSL. The first row and each repetition
onset wake a worker thread, which raises the trigger line and sends the markers, so neither a GPIO
write nor a command ever runs inside a cycle. :meth:`TrialSync.finish` (after the loop) sends the
safe stop, lowers the line, and writes the two sync events of :mod:`bowden.runtime.sync_events`.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from collections.abc import Callable, Sequence
from typing import Final

from bowden.hardware.trigger import TriggerLine
from bowden.runtime.loop import Row
from bowden.runtime.lsl_outlets import LOOP_ROW_INDICES, LslOutlets
from bowden.runtime.sync_events import (
    MARKER_REPETITION,
    MARKER_SAFE_STOP,
    MARKER_SESSION,
    MARKER_TRIAL_END,
    MARKER_TRIAL_START,
    SYNC_KIND,
    SyncEvent,
    marker_text,
)

_STOP: Final = object()


class TrialSync:
    """Sync signals of one trial; use ``sync.row`` as a loop sink, then call :meth:`finish`.

    Parameters
    ----------
    trial_id
        The store's id of the trial (None when not recorded): in every marker.
    trigger
        The trigger line, or None.
    lsl
        The LSL outlets, or None.
    on_event
        Where the sync events go (``Recorder.event``), or None.
    repetition_onsets_s
        Loop times at which the reference starts each repetition (a marker each).
    session
        Fields of the session marker (store, participant, condition, speed...).
    """

    def __init__(
        self,
        *,
        trial_id: int | None,
        trigger: TriggerLine | None = None,
        lsl: LslOutlets | None = None,
        on_event: Callable[[float, str, str], None] | None = None,
        repetition_onsets_s: Sequence[float] = (),
        session: dict[str, object] | None = None,
    ) -> None:
        self.trial_id = trial_id
        self.trigger = trigger
        self.lsl = lsl
        self.on_event = on_event
        self._onsets = list(repetition_onsets_s)
        self._next_onset = 0
        self._zero_s = math.inf  # host time of loop time zero (monotonic clock), s
        self._start: tuple[float, float] | None = None  # (host time, uncertainty) of the start edge
        self._queue: queue.SimpleQueue[tuple[str, float] | object] = queue.SimpleQueue()
        self.error: BaseException | None = None
        # After finish: how long each edge's send took (the edge lies within), s; ``bowden run`` reports it.
        self.edge_uncertainties_s: dict[str, float] = {}
        self._thread = threading.Thread(target=self._work, name="trial-sync", daemon=True)
        self._thread.start()
        if lsl is not None:
            lsl.marker(marker_text(MARKER_SESSION, trial=trial_id, **(session or {})), time.monotonic())

    # --- loop side ---------------------------------------------------------------------------------
    def row(self, row: Row) -> None:
        """Called once per cycle with the recorded row: one clock read, a comparison, a queue append."""
        now = time.monotonic()
        t = row[0]
        if now - t < self._zero_s:
            first = self._zero_s == math.inf
            self._zero_s = now - t
            if first:
                self._queue.put(("start", 0.0))
        onsets = self._onsets
        if self._next_onset < len(onsets) and t >= onsets[self._next_onset]:
            self._queue.put(("repetition", onsets[self._next_onset]))
            self._next_onset += 1
        if self.lsl is not None:
            self.lsl.sample([row[i] for i in LOOP_ROW_INDICES], self._zero_s + t)

    # --- after the loop ----------------------------------------------------------------------------
    def finish(self, *, stop_time_s: float, reason: str, clean: bool) -> None:
        """Safe-stop marker, trigger low, trial-end marker, and both sync events into the store."""
        self._queue.put(_STOP)
        self._thread.join()
        if self._start is None:  # the loop never ran a cycle: there is no trial to mark
            return
        zero = self._zero_s
        if self.lsl is not None:
            self.lsl.marker(
                marker_text(
                    MARKER_SAFE_STOP, trial=self.trial_id, time_s=stop_time_s, reason=reason, clean=clean
                ),
                zero + stop_time_s,
            )
        end_host, end_spread = self._edge(False)
        if self.lsl is not None:
            self.lsl.marker(
                marker_text(MARKER_TRIAL_END, trial=self.trial_id, time_s=end_host - zero), end_host
            )
        self.edge_uncertainties_s = {"start": self._start[1], "end": end_spread}
        if self.on_event is not None:
            line = self.trigger.description if self.trigger is not None else None
            start_host, start_spread = self._start
            for edge, host, spread in (("start", start_host, start_spread), ("end", end_host, end_spread)):
                event = SyncEvent(
                    edge=edge,  # type: ignore[arg-type]
                    time_s=host - zero,
                    host_time_s=host,
                    uncertainty_s=spread,
                    trigger=line,
                )
                self.on_event(event.time_s, SYNC_KIND, event.message())

    def _edge(self, high: bool) -> tuple[float, float]:
        """Toggle the line (or just read the clock): host time of the edge and its uncertainty, s."""
        if self.trigger is None:
            now = time.monotonic()
            return now, 0.0
        before, after = self.trigger.set(high)
        return 0.5 * (before + after), after - before

    def _work(self) -> None:
        trial = self.trial_id
        while True:
            item = self._queue.get()
            if not isinstance(item, tuple):  # _STOP
                return
            kind: str = item[0]
            onset: float = item[1]
            try:
                if kind == "start":
                    host, spread = self._edge(True)
                    self._start = (host, spread)
                    if self.lsl is not None:
                        text = marker_text(MARKER_TRIAL_START, trial=trial, time_s=host - self._zero_s)
                        self.lsl.marker(text, host)
                elif self.lsl is not None:
                    number = self._onsets.index(onset) + 1
                    text = marker_text(MARKER_REPETITION, trial=trial, time_s=onset, repetition=number)
                    self.lsl.marker(text, self._zero_s + onset)
            except Exception as error:  # a failed trigger must not kill the thread silently
                self.error = error
