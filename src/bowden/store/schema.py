"""Schema of the study store (SQLite): its version, the check every opener runs, and the trial tables.

The other tables and their migrations are in :mod:`bowden.store.tables`; each table's rows have one
writer in :mod:`bowden.store` (docs/design.md, "Packages and the rules between them").

Why SQLite: it is in the standard library (nothing to install on the BeagleBone), one file per study,
and its write-ahead log makes every committed transaction survive a crash or ``kill -9`` of the
writer — the property the recorder needs (docs/design.md: lose at most the last 0.2 s, never what was
committed). Readers (the live console, the analysis) can read while a trial is being written.

Tables (``STRICT``: a wrong type is an error, not a silent conversion):

``trials``
    one row per recorded trial: ``id``; ``participant`` (pseudonymous id, never a name);
    ``condition`` (one of ``contracts.CONDITIONS`` or a lab's own, ``contracts.is_protocol_name``);
    ``speed`` (one of ``contracts.SPEEDS`` or a lab's own, or NULL for a free run); ``support``
    (fraction of gravity support, NULL for the pretension and no-suit conditions); ``started_utc`` /
    ``ended_utc`` (ISO 8601; ``ended_utc`` NULL while recording or after a crash); ``stop_reason``
    (why the loop stopped); ``metadata`` (a JSON object: rate, backend, model file, software
    version, the speed's ``speed_peak_deg_s``...).
``sample_chunks``
    the control cycles in blocks: ``trial_id``; ``start_time_s`` / ``end_time_s`` (the block's first
    and last loop time); ``row_count``; ``data``, the columns of ``contracts.TRIAL_COLUMNS`` (SI
    units as named; float64, the state and fault codes int64; NaN kept, e.g. no load cell) encoded
    losslessly by :mod:`bowden.store.column_codec`. The recorder commits a block every 0.1 s and
    merges a trial's blocks into blocks of up to :data:`~bowden.store.sample_chunks.CHUNK_ROWS`
    rows as it goes (:mod:`bowden.store.sample_chunks` reads and writes them).
``events``
    things that happened during a trial, in loop time: ``trial_id``, ``time_s``, ``kind``
    (``start``, ``safe_stop``, ``fault``, ...), ``message``.

Version 3 and older stores kept one row per control cycle in a ``samples`` table (and the study
store's EMG one row per trial and muscle in ``emg``): about 110 bytes a cycle with its index, against
about 40 in chunks.
Those :data:`LEGACY_TABLES` are read as they are (and their trials deleted or replaced as before),
never created; new trials in an old store go to the chunk tables.

The version is kept in ``PRAGMA user_version``. Before anything changes a file, :func:`check_store`
makes sure it is a bowden store (or an empty file): a file from a newer bowden, an SQLite file of
another program (tables bowden does not make) or a store of an older layout (a table lacking a column
bowden reads) is refused with a :class:`~bowden.errors.StoreError` naming the file and the problem,
and left byte for byte as it was (no WAL switch, no new table, no version stamp).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Mapping
from typing import Final

from bowden.contracts import TRIAL_COLUMNS
from bowden.errors import StoreError

# The study store's file name wherever bowden makes or looks for one (serve, run, study, analyze).
STORE_FILE_NAME: Final = "study.db"

# 2: the participant registry's columns and the session plans (bowden.store.tables).
# 3: custom protocols: conditions and speeds named by contracts.is_protocol_name; the questionnaires
#    table's CHECK follows that rule (bowden.store.tables.migrate_questionnaires).
# 4: samples and EMG in compressed chunks (sample_chunks, emg_chunks); samples and emg are legacy.
# 5: emg_chunks.offset_v: imported EMG keeps its file's codes and scaling (volts = code × gain +
#    offset_v); an older bowden would ignore the offset, so it must refuse such a store.
# 6: outcomes.trial_id: each outcome row names its trial (two trials of one participant, condition and
#    speed stay apart); an older bowden's seven-value INSERT would fail on the table.
SCHEMA_VERSION: Final = 6

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

SAMPLE_CHUNKS_DDL: Final = """
CREATE TABLE IF NOT EXISTS sample_chunks (
    trial_id INTEGER NOT NULL REFERENCES trials(id),
    start_time_s REAL NOT NULL,
    end_time_s REAL NOT NULL,
    row_count INTEGER NOT NULL CHECK (row_count > 0),
    data BLOB NOT NULL
) STRICT
"""

SAMPLE_CHUNKS_INDEX_DDL: Final = (
    "CREATE INDEX IF NOT EXISTS sample_chunks_by_trial_time ON sample_chunks (trial_id, start_time_s)"
)

EVENTS_DDL: Final = """
CREATE TABLE IF NOT EXISTS events (
    trial_id INTEGER NOT NULL REFERENCES trials(id),
    time_s REAL,
    kind TEXT NOT NULL,
    message TEXT NOT NULL
) STRICT
"""

# Every table a bowden store may hold, with the columns bowden reads from it. create_schema makes
# trials, sample_chunks and events; bowden.store.tables lays out the others (the study store, the
# questionnaire forms, the participant registry and the session plans make them as they open a file);
# older stores may hold the LEGACY_TABLES. Whichever opens a file first can tell a bowden store from
# another program's file before changing anything.
# tests/runtime/test_store_schema.py checks this list against the tables those modules create.
STORE_TABLES: Final[Mapping[str, tuple[str, ...]]] = {
    "trials": (
        "id", "participant", "condition", "speed", "support", "started_utc", "ended_utc",
        "stop_reason", "metadata",
    ),
    "sample_chunks": ("trial_id", "start_time_s", "end_time_s", "row_count", "data"),
    "samples": ("trial_id", *TRIAL_COLUMNS),
    "events": ("trial_id", "time_s", "kind", "message"),
    "participants": (
        "id", "sex", "height_m", "mass_kg", "metadata", "arm_side", "hand_load_kg", "age_years",
        "registered_utc",
    ),
    "emg_chunks": (
        "trial_id", "muscle", "first_sample", "sample_count", "rate_hz", "start_time_s", "gain", "data",
        "offset_v",
    ),
    "emg": ("trial_id", "muscle", "rate_hz", "start_time_s", "gain", "data"),
    "questionnaires": ("participant", "condition", "questionnaire", "item", "score", "submitted_utc"),
    "outcomes": ("participant", "condition", "speed", "repetition", "phase", "measure", "value", "trial_id"),
    "artifacts": ("name", "content", "updated_utc"),
    "sessions": (
        "id", "participant", "protocol", "order_rule", "seed", "sequence", "condition_order", "created_utc",
    ),
    "plan_steps": ("session_id", "position", "condition", "speed", "repetitions", "skip_reason"),
    "session_trials": ("trial_id", "session_id", "position", "status", "reason", "updated_utc"),
    "session_notes": ("session_id", "participant", "condition", "position", "kind", "reason", "noted_utc"),
}
# Tables of version 3 and older stores: read, never created (their data moved to the chunk tables).
LEGACY_TABLES: Final = frozenset({"samples", "emg"})
# Columns added to a table after its first release. A store written before lacks them until the
# migration adds them (bowden.store.tables.migrate_participants), so their absence
# does not make the file unreadable.
ADDED_COLUMNS: Final[Mapping[str, frozenset[str]]] = {
    "participants": frozenset({"arm_side", "hand_load_kg", "age_years", "registered_utc"}),
    "emg_chunks": frozenset({"offset_v"}),  # schema 5 (bowden.store.tables.migrate_emg_chunks)
    "outcomes": frozenset({"trial_id"}),  # schema 6 (bowden.store.tables.migrate_outcomes)
}


def configure_connection(connection: sqlite3.Connection, *, synchronous: str = "FULL") -> None:
    """WAL journal (crash-safe commits, readers alongside the writer) and the fsync policy.

    Runs :func:`check_store` first, so a file that is not a bowden store is refused unchanged.
    ``synchronous=FULL`` fsyncs the log at every commit, so a commit also survives a power cut (the
    suit runs on a battery); ``NORMAL`` survives process crashes only.
    """
    if synchronous not in ("FULL", "NORMAL"):
        raise StoreError(f"synchronous must be FULL or NORMAL, got {synchronous!r}")
    # Switching to WAL rewrites the file header: check first that the file is ours to change.
    check_store(connection)
    mode = connection.execute("PRAGMA journal_mode=WAL").fetchone()[0]
    if str(mode).lower() != "wal":
        raise StoreError(f"the study store needs WAL journaling, the file system gave {mode!r}")
    connection.execute(f"PRAGMA synchronous={synchronous}")
    connection.execute("PRAGMA foreign_keys=ON")


def check_store(connection: sqlite3.Connection) -> None:
    """Refuse a file that is not a bowden store (or an empty file), without changing it.

    A store is every file whose tables are all bowden's (:data:`STORE_TABLES`), each with at least the
    columns bowden reads, and whose schema version is at most :data:`SCHEMA_VERSION`. A file without
    tables (new) passes. Only reads are made, so a refused file is left exactly as it was.

    Raises
    ------
    StoreError
        Naming the file and what is wrong: not an SQLite database, a newer schema version, tables of
        another program, or bowden tables lacking columns (an older layout).
    """
    name = _file_name(connection)
    try:
        version = int(connection.execute("PRAGMA user_version").fetchone()[0])
        objects = connection.execute(
            "SELECT name, type FROM sqlite_master WHERE type IN ('table', 'view') "
            "AND name NOT LIKE 'sqlite\\_%' ESCAPE '\\' ORDER BY name"
        ).fetchall()
        columns = {
            table: {str(row[1]) for row in connection.execute(f'PRAGMA table_info("{table}")')}
            for table, kind in objects
            if table in STORE_TABLES and kind == "table"
        }
    except sqlite3.Error as error:
        raise StoreError(f"{name}: cannot be read as a bowden study store ({error})") from None
    if version > SCHEMA_VERSION:
        raise StoreError(
            f"{name}: the store has schema version {version}, this bowden knows up to {SCHEMA_VERSION}: "
            "upgrade bowden"
        )
    foreign = [f"{table!r}" for table, kind in objects if table not in STORE_TABLES or kind != "table"]
    if foreign:
        raise StoreError(
            f"{name}: not a bowden study store: it holds {', '.join(foreign)}, which bowden does not "
            f"make (bowden's tables: {', '.join(STORE_TABLES)}); the file was left unchanged"
        )
    for table, present in columns.items():
        added = ADDED_COLUMNS.get(table, frozenset())
        missing = [column for column in STORE_TABLES[table] if column not in present and column not in added]
        if missing:
            raise StoreError(
                f"{name}: table {table!r} lacks the column(s) {', '.join(missing)}: an older store "
                "layout (or another program's table) that this bowden cannot read; the file was left "
                "unchanged"
            )


def create_schema(connection: sqlite3.Connection) -> None:
    """Create the tables if missing and stamp the version, after :func:`check_store` accepts the file."""
    check_store(connection)
    with connection:
        for ddl in (TRIALS_DDL, SAMPLE_CHUNKS_DDL, SAMPLE_CHUNKS_INDEX_DDL, EVENTS_DDL):
            connection.execute(ddl)
        connection.execute(f"PRAGMA user_version={SCHEMA_VERSION}")


def _file_name(connection: sqlite3.Connection) -> str:
    """The path of the connection's main database, for error messages."""
    try:
        for _seq, schema, path in connection.execute("PRAGMA database_list"):
            if schema == "main":
                return str(path) if path else "the in-memory store"
    except sqlite3.Error:
        pass
    return "the study store"
