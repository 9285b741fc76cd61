"""Schema of the trial-sample store (SQLite), the base the full study store builds on.

Why SQLite: it is in the standard library (nothing to install on the BeagleBone), one file per study,
and its write-ahead log makes every committed transaction survive a crash or ``kill -9`` of the
writer — the property the recorder needs (DESIGN.md: lose at most the last 0.2 s, never what was
committed). Readers (the live console, the analysis) can read while a trial is being written.

Tables (``STRICT``: a wrong type is an error, not a silent conversion):

``trials``
    one row per recorded trial: ``id``; ``participant`` (pseudonymous id, never a name);
    ``condition`` (one of ``contracts.CONDITIONS``); ``speed`` (one of ``contracts.SPEEDS``, or NULL
    for a free run); ``support`` (fraction of gravity support, NULL for the pretension and no-suit
    conditions); ``started_utc`` / ``ended_utc`` (ISO 8601; ``ended_utc`` NULL while recording or
    after a crash); ``stop_reason`` (why the loop stopped); ``metadata`` (a JSON object: rate,
    backend, model file, software version...).
``samples``
    one row per control cycle: ``trial_id`` then the columns of ``contracts.TRIAL_COLUMNS``
    (SI units as named). SQLite has no NaN: a NaN (e.g. no load cell) is stored as NULL.
``events``
    things that happened during a trial, in loop time: ``trial_id``, ``time_s``, ``kind``
    (``start``, ``safe_stop``, ``fault``, ...), ``message``.

The version is kept in ``PRAGMA user_version``; :func:`create_schema` refuses a newer file.
"""

from __future__ import annotations

import sqlite3
from typing import Final

from bowden.contracts import TRIAL_COLUMNS, TRIAL_FAULT, TRIAL_STATE, TRIAL_TIME
from bowden.errors import StoreError

SCHEMA_VERSION: Final = 1

_INTEGER_COLUMNS: Final = frozenset({TRIAL_STATE, TRIAL_FAULT})
_REQUIRED_COLUMNS: Final = frozenset({TRIAL_TIME, TRIAL_STATE, TRIAL_FAULT})


def _sample_column(name: str) -> str:
    kind = "INTEGER" if name in _INTEGER_COLUMNS else "REAL"
    null = " NOT NULL" if name in _REQUIRED_COLUMNS else ""
    return f"    {name} {kind}{null}"


TRIALS_DDL: Final = """
CREATE TABLE IF NOT EXISTS trials (
    id INTEGER PRIMARY KEY,
    participant TEXT NOT NULL,
    condition TEXT NOT NULL,
    speed TEXT,
    support REAL CHECK (support IS NULL OR (support >= 0.0 AND support <= 1.0)),
    started_utc TEXT NOT NULL,
    ended_utc TEXT,
    stop_reason TEXT,
    metadata TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(metadata) AND json_type(metadata) = 'object')
) STRICT
"""

SAMPLES_DDL: Final = (
    "\nCREATE TABLE IF NOT EXISTS samples (\n"
    "    trial_id INTEGER NOT NULL REFERENCES trials(id),\n"
    + ",\n".join(_sample_column(name) for name in TRIAL_COLUMNS)
    + "\n) STRICT\n"
)

SAMPLES_INDEX_DDL: Final = (
    f"CREATE INDEX IF NOT EXISTS samples_by_trial_time ON samples (trial_id, {TRIAL_TIME})"
)

EVENTS_DDL: Final = """
CREATE TABLE IF NOT EXISTS events (
    trial_id INTEGER NOT NULL REFERENCES trials(id),
    time_s REAL,
    kind TEXT NOT NULL,
    message TEXT NOT NULL
) STRICT
"""

INSERT_SAMPLE_SQL: Final = (
    f"INSERT INTO samples (trial_id, {', '.join(TRIAL_COLUMNS)}) "
    f"VALUES ({', '.join('?' * (len(TRIAL_COLUMNS) + 1))})"
)


def configure_connection(connection: sqlite3.Connection, *, synchronous: str = "FULL") -> None:
    """WAL journal (crash-safe commits, readers alongside the writer) and the fsync policy.

    ``synchronous=FULL`` fsyncs the log at every commit, so a commit also survives a power cut (the
    suit runs on a battery); ``NORMAL`` survives process crashes only.
    """
    if synchronous not in ("FULL", "NORMAL"):
        raise StoreError(f"synchronous must be FULL or NORMAL, got {synchronous!r}")
    mode = connection.execute("PRAGMA journal_mode=WAL").fetchone()[0]
    if str(mode).lower() != "wal":
        raise StoreError(f"the study store needs WAL journaling, the file system gave {mode!r}")
    connection.execute(f"PRAGMA synchronous={synchronous}")
    connection.execute("PRAGMA foreign_keys=ON")


def create_schema(connection: sqlite3.Connection) -> None:
    """Create the tables if missing and stamp the version; refuse files from a newer bowden."""
    version = int(connection.execute("PRAGMA user_version").fetchone()[0])
    if version > SCHEMA_VERSION:
        raise StoreError(
            f"the store has schema version {version}, this bowden knows up to {SCHEMA_VERSION}: "
            "upgrade bowden"
        )
    with connection:
        for ddl in (TRIALS_DDL, SAMPLES_DDL, SAMPLES_INDEX_DDL, EVENTS_DDL):
            connection.execute(ddl)
        connection.execute(f"PRAGMA user_version={SCHEMA_VERSION}")
