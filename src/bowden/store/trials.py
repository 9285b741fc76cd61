"""The ``trials`` and ``events`` tables: what identifies a trial, and their one writer.

The recorder (live trials, :mod:`bowden.runtime.recorder`) and the study store (simulated trials
written whole, :mod:`bowden.store.study_store`) both open, close and annotate trials through these
functions, so a trial row means the same whichever wrote it. Each runs inside the caller's
transaction (``with connection:``), so a trial and its samples commit together.
"""

from __future__ import annotations

import json
import math
import sqlite3
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, Final

from bowden.contracts import PROTOCOL_NAME_RULE, is_participant_id, is_protocol_name
from bowden.errors import ParameterError

# (trial_id, time_s or None, kind, message): one row of ``events``.
Event = tuple[int | None, float | None, str, str]

_INSERT_EVENT: Final = "INSERT INTO events (trial_id, time_s, kind, message) VALUES (?, ?, ?, ?)"


def utc_now_iso() -> str:
    """Current UTC time, ISO 8601 with microseconds."""
    return datetime.now(UTC).isoformat(timespec="microseconds")


@dataclass(frozen=True, kw_only=True)
class TrialInfo:
    """What identifies a trial in the store.

    Parameters
    ----------
    participant
        Pseudonymous participant id (never a name): :func:`bowden.contracts.is_participant_id`.
    condition
        One of ``bowden.contracts.CONDITIONS``, or a lab's own condition
        (:mod:`bowden.protocol.catalogue`, named by :func:`bowden.contracts.is_protocol_name`).
    speed
        One of ``bowden.contracts.SPEEDS``, a lab's own speed (the same rule), or None for a free run.
    support
        Gravity-support fraction 0–1, or None (pretension, no suit).
    metadata
        JSON-serialisable details (rate, backend, model file, versions...).
    """

    participant: str
    condition: str
    speed: str | None = None
    support: float | None = None
    metadata: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not is_participant_id(self.participant):
            raise ParameterError(
                f"TrialInfo.participant must be a pseudonymous id (1–4 capital letters then 1–4 digits, "
                f"e.g. P07; never a name), got {self.participant!r}"
            )
        # What a name means (support, peak speed) is the protocol's business; the store takes any
        # name by the one rule, and the trial records the support it ran.
        if not is_protocol_name(self.condition):
            raise ParameterError(f"TrialInfo.condition must be {PROTOCOL_NAME_RULE}, got {self.condition!r}")
        if self.speed is not None and not is_protocol_name(self.speed):
            raise ParameterError(f"TrialInfo.speed must be {PROTOCOL_NAME_RULE} or None, got {self.speed!r}")
        if self.support is not None and not (math.isfinite(self.support) and 0.0 <= self.support <= 1.0):
            raise ParameterError(f"TrialInfo.support must be in [0, 1] or None, got {self.support!r}")
        try:
            json.dumps(dict(self.metadata), allow_nan=False)
        except (TypeError, ValueError) as error:
            raise ParameterError(f"TrialInfo.metadata must be JSON-serialisable: {error}") from None


def insert_trial(connection: sqlite3.Connection, trial: TrialInfo) -> int:
    """Open a trial (no end time yet); return its id."""
    cursor = connection.execute(
        "INSERT INTO trials (participant, condition, speed, support, started_utc, metadata) "
        "VALUES (?, ?, ?, ?, ?, ?)",
        (trial.participant, trial.condition, trial.speed, trial.support, utc_now_iso(),
         json.dumps(dict(trial.metadata), allow_nan=False)),
    )
    return int(cursor.lastrowid or 0)


def end_trial(connection: sqlite3.Connection, trial_id: int | None, stop_reason: str | None) -> None:
    """Close a trial: its end time (now) and why it stopped."""
    connection.execute(
        "UPDATE trials SET ended_utc = ?, stop_reason = ? WHERE id = ?",
        (utc_now_iso(), stop_reason, trial_id),
    )


def insert_events(connection: sqlite3.Connection, events: Iterable[Event]) -> None:
    """Append events ``(trial_id, time_s, kind, message)``."""
    connection.executemany(_INSERT_EVENT, events)


def replace_event(connection: sqlite3.Connection, trial_id: int, kind: str, message: str) -> None:
    """Make ``message`` the trial's one event of ``kind`` (no loop time: it happened after the trial)."""
    connection.execute("DELETE FROM events WHERE trial_id = ? AND kind = ?", (trial_id, kind))
    connection.execute(_INSERT_EVENT, (trial_id, None, kind, message))


def delete_trial_row(connection: sqlite3.Connection, trial_id: int) -> None:
    """Delete a trial's row and its events (its samples and EMG go first, through their modules)."""
    connection.execute("DELETE FROM events WHERE trial_id = ?", (trial_id,))
    connection.execute("DELETE FROM trials WHERE id = ?", (trial_id,))


def condition_supports(connection: sqlite3.Connection) -> list[tuple[str, float]]:
    """Each condition recorded with a support, and that support (a pair once, in recording order)."""
    rows = connection.execute(
        "SELECT DISTINCT condition, support FROM trials WHERE support IS NOT NULL ORDER BY id"
    )
    return [(str(name), float(support)) for name, support in rows]


def speed_peaks(connection: sqlite3.Connection) -> list[tuple[str, float]]:
    """Each speed recorded with its peak (°/s, the trial's ``speed_peak_deg_s``), in recording order."""
    rows = connection.execute(
        "SELECT DISTINCT speed, json_extract(metadata, '$.speed_peak_deg_s') FROM trials "
        "WHERE speed IS NOT NULL AND json_extract(metadata, '$.speed_peak_deg_s') IS NOT NULL "
        "ORDER BY id"
    )
    return [(str(name), float(peak)) for name, peak in rows]
