"""The sync events a trial leaves in the store, and the text of bowden's LSL markers.

Each recorded trial gets two events of kind ``sync`` (its start and its end), written when the trigger
line was toggled and the marker sent. Their message is a JSON object:

``edge``
    ``"start"`` or ``"end"``;
``host_time_s``
    when it was sent on the host's monotonic clock (``CLOCK_MONOTONIC``, which is also Lab Streaming
    Layer's ``local_clock`` on Linux), s: one clock for every trial of a session, so the import fits
    the amplifier's drift over all of them;
``uncertainty_s``
    how long the send took (the edge happened within it; ``host_time_s`` is its middle);
``trigger``
    the trigger line toggled (``"gpio:/dev/gpiochip1:28"``, ``"command"``), or null.

The event's ``time_s`` is the same instant on the trial's loop clock, so ``host_time_s - time_s`` is
where the trial's time zero lies on the host clock. Markers are JSON objects too, with ``event``
(``session``, ``trial_start``, ``trial_end``, ``repetition``, ``safe_stop``), the ``trial`` id and
the loop time ``time_s``, so a recording made with LabRecorder can be matched to the store by id.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, Final, Literal

from bowden.errors import RecordingError

SYNC_KIND: Final = "sync"
Edge = Literal["start", "end"]

MARKER_SESSION: Final = "session"
MARKER_TRIAL_START: Final = "trial_start"
MARKER_TRIAL_END: Final = "trial_end"
MARKER_REPETITION: Final = "repetition"
MARKER_SAFE_STOP: Final = "safe_stop"
MARKER_EDGES: Final[dict[str, Edge]] = {MARKER_TRIAL_START: "start", MARKER_TRIAL_END: "end"}


@dataclass(frozen=True, kw_only=True)
class SyncEvent:
    """One edge of a trial: loop time and host time of the same instant, s."""

    edge: Edge
    time_s: float
    host_time_s: float
    uncertainty_s: float = 0.0
    trigger: str | None = None

    def message(self) -> str:
        return json.dumps(
            {
                "edge": self.edge,
                "host_time_s": self.host_time_s,
                "uncertainty_s": self.uncertainty_s,
                "trigger": self.trigger,
            },
            allow_nan=False,
        )

    @property
    def zero_host_time_s(self) -> float:
        """Host time of the trial's loop time zero, s."""
        return self.host_time_s - self.time_s

    @classmethod
    def from_event(cls, time_s: float | None, message: str) -> SyncEvent:
        """Parse an events row; :class:`RecordingError` naming the problem if it is not a sync event."""
        try:
            content: Any = json.loads(message)
            edge, host = content["edge"], float(content["host_time_s"])
            uncertainty = float(content.get("uncertainty_s", 0.0))
        except (ValueError, KeyError, TypeError):
            raise RecordingError(f"a sync event's message is malformed: {message[:80]!r}") from None
        if edge not in ("start", "end") or time_s is None or not (
            math.isfinite(host) and math.isfinite(time_s)
        ):
            raise RecordingError(f"a sync event is incomplete: {message[:80]!r}")
        trigger = content.get("trigger")
        return cls(
            edge=edge,
            time_s=float(time_s),
            host_time_s=host,
            uncertainty_s=uncertainty,
            trigger=str(trigger) if trigger is not None else None,
        )


def marker_text(event: str, **fields: object) -> str:
    """The JSON text of one marker (keys sorted, so the same marker is the same text)."""
    return json.dumps({"event": event, **fields}, sort_keys=True, allow_nan=False)


def parse_marker(text: str) -> dict[str, Any] | None:
    """A bowden marker's fields, or None for text that is not one (other software's markers)."""
    try:
        content = json.loads(text)
    except ValueError:
        return None
    return content if isinstance(content, dict) and isinstance(content.get("event"), str) else None
