"""The study tables beyond the trials (:mod:`bowden.store.schema`) and their migrations: one place.

``participants`` (the registry: pseudonymous id and anthropometrics, never a name), ``questionnaires``
(one row per answered item), the session plans (``sessions``, ``plan_steps``, ``session_trials``,
``session_notes``), the raw sEMG in ``emg_chunks``, the analysis's ``outcomes`` and the study's
``artifacts``. Each ``migrate_*`` brings an older store's table to this bowden's layout inside the
caller's transaction; :func:`create_study_tables` makes or migrates them all (``bowden study``,
``bowden analyze``); the server makes the ones it writes as it opens the file.
"""

from __future__ import annotations

import sqlite3
from typing import Final

from bowden.contracts import (
    BORG_HIGH,
    BORG_LOW,
    LIKERT_HIGH,
    LIKERT_LOW,
    QUESTIONNAIRE_BORG_RPE,
    QUESTIONNAIRES,
)

PARTICIPANTS_DDL: Final = """
CREATE TABLE IF NOT EXISTS participants (
    id TEXT PRIMARY KEY,
    sex TEXT NOT NULL CHECK (sex IN ('female', 'male')),
    height_m REAL NOT NULL,
    mass_kg REAL NOT NULL,
    metadata TEXT NOT NULL DEFAULT '{}',
    arm_side TEXT CHECK (arm_side IS NULL OR arm_side IN ('left', 'right')),
    hand_load_kg REAL CHECK (hand_load_kg IS NULL OR hand_load_kg BETWEEN 0.0 AND 5.0),
    age_years INTEGER CHECK (age_years IS NULL OR age_years BETWEEN 16 AND 100),
    registered_utc TEXT
) STRICT
"""
# Columns the registry added to the table (schema 2); older stores lack them until migrated.
PARTICIPANT_ADDED_COLUMNS: Final = {
    "arm_side": "TEXT CHECK (arm_side IS NULL OR arm_side IN ('left', 'right'))",
    "hand_load_kg": "REAL CHECK (hand_load_kg IS NULL OR hand_load_kg BETWEEN 0.0 AND 5.0)",
    "age_years": "INTEGER CHECK (age_years IS NULL OR age_years BETWEEN 16 AND 100)",
    "registered_utc": "TEXT",
}

# The participant CHECK is contracts.is_participant_id in SQL (only capitals and digits, no capital
# after a digit, 1–4 capitals then 1–4 digits), so the database refuses what bowden refuses.
_CAPITALS: Final = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
_QUESTIONNAIRE_LIST: Final = ", ".join(f"'{q}'" for q in QUESTIONNAIRES)

QUESTIONNAIRES_DDL: Final = f"""
CREATE TABLE IF NOT EXISTS questionnaires (
    participant TEXT NOT NULL
        CHECK (participant NOT GLOB '*[^A-Z0-9]*' AND participant NOT GLOB '*[0-9]*[A-Z]*'
               AND length(rtrim(participant, '0123456789')) BETWEEN 1 AND 4
               AND length(ltrim(participant, '{_CAPITALS}')) BETWEEN 1 AND 4),
    condition TEXT NOT NULL CHECK (condition GLOB '[A-Za-z]*' AND condition NOT GLOB '*[^A-Za-z0-9_]*'
                                   AND length(condition) <= 24),
    questionnaire TEXT NOT NULL CHECK (questionnaire IN ({_QUESTIONNAIRE_LIST})),
    item TEXT NOT NULL,
    score INTEGER NOT NULL CHECK (
        CASE questionnaire WHEN '{QUESTIONNAIRE_BORG_RPE}' THEN score BETWEEN {BORG_LOW} AND {BORG_HIGH}
        ELSE score BETWEEN {LIKERT_LOW} AND {LIKERT_HIGH} END),
    submitted_utc TEXT NOT NULL,
    PRIMARY KEY (participant, condition, questionnaire, item)
) STRICT
"""
QUESTIONNAIRE_COLUMNS: Final = ("participant", "condition", "questionnaire", "item", "score", "submitted_utc")
# The CHECK of stores written before custom protocols (schema 3): the paper's four conditions only.
_PAPER_ONLY_CHECK: Final = "CHECK (condition IN ("

SESSION_DDL: Final = (
    """
CREATE TABLE IF NOT EXISTS sessions (
    id INTEGER PRIMARY KEY,
    participant TEXT NOT NULL REFERENCES participants(id),
    protocol TEXT NOT NULL CHECK (json_valid(protocol)),
    order_rule TEXT NOT NULL,
    seed INTEGER NOT NULL,
    sequence INTEGER NOT NULL,
    condition_order TEXT NOT NULL CHECK (json_valid(condition_order)),
    created_utc TEXT NOT NULL
) STRICT
""",
    """
CREATE TABLE IF NOT EXISTS plan_steps (
    session_id INTEGER NOT NULL REFERENCES sessions(id),
    position INTEGER NOT NULL,
    condition TEXT NOT NULL,
    speed TEXT NOT NULL,
    repetitions INTEGER NOT NULL,
    skip_reason TEXT,
    PRIMARY KEY (session_id, position)
) STRICT
""",
    """
CREATE TABLE IF NOT EXISTS session_trials (
    trial_id INTEGER PRIMARY KEY REFERENCES trials(id),
    session_id INTEGER NOT NULL REFERENCES sessions(id),
    position INTEGER NOT NULL,
    status TEXT NOT NULL CHECK (status IN ('running', 'completed', 'stopped', 'redone')),
    reason TEXT,
    updated_utc TEXT NOT NULL
) STRICT
""",
    """
CREATE TABLE IF NOT EXISTS session_notes (
    session_id INTEGER REFERENCES sessions(id),
    participant TEXT NOT NULL,
    condition TEXT,
    position INTEGER,
    kind TEXT NOT NULL,
    reason TEXT NOT NULL,
    noted_utc TEXT NOT NULL
) STRICT
""",
)

EMG_CHUNKS_DDL: Final = """
CREATE TABLE IF NOT EXISTS emg_chunks (
    trial_id INTEGER NOT NULL REFERENCES trials(id),
    muscle TEXT NOT NULL,
    first_sample INTEGER NOT NULL CHECK (first_sample >= 0),
    sample_count INTEGER NOT NULL CHECK (sample_count > 0),
    rate_hz REAL NOT NULL,
    start_time_s REAL NOT NULL,
    gain REAL NOT NULL,
    data BLOB NOT NULL,
    offset_v REAL NOT NULL DEFAULT 0.0,
    PRIMARY KEY (trial_id, muscle, first_sample)
) STRICT
"""

OUTCOMES_DDL: Final = """
CREATE TABLE IF NOT EXISTS outcomes (
    participant TEXT NOT NULL,
    condition TEXT NOT NULL,
    speed TEXT NOT NULL,
    repetition INTEGER NOT NULL,
    phase TEXT NOT NULL,
    measure TEXT NOT NULL,
    value REAL,
    trial_id INTEGER
) STRICT
"""

ARTIFACTS_DDL: Final = """
CREATE TABLE IF NOT EXISTS artifacts (
    name TEXT PRIMARY KEY,
    content TEXT NOT NULL,
    updated_utc TEXT NOT NULL
) STRICT
"""


def migrate_participants(connection: sqlite3.Connection) -> None:
    """Create the table, or add the registry's columns to an older one (inside the caller's transaction)."""
    connection.execute(PARTICIPANTS_DDL)
    present = {str(row[1]) for row in connection.execute("PRAGMA table_info(participants)")}
    for column, definition in PARTICIPANT_ADDED_COLUMNS.items():
        if column not in present:
            connection.execute(f"ALTER TABLE participants ADD COLUMN {column} {definition}")


def migrate_questionnaires(connection: sqlite3.Connection) -> None:
    """Create the table, or rebuild an older one whose CHECK allows only the paper's conditions.

    SQLite cannot change a CHECK in place: the answers are copied into a table of the new layout,
    which then takes the old one's name (SQLite's documented procedure), inside the caller's
    transaction, so a failure leaves the old table as it was.
    """
    row = connection.execute(
        "SELECT sql FROM sqlite_master WHERE type = 'table' AND name = 'questionnaires'"
    ).fetchone()
    if row is None or _PAPER_ONLY_CHECK not in str(row[0]):
        connection.execute(QUESTIONNAIRES_DDL)
        return
    columns = ", ".join(QUESTIONNAIRE_COLUMNS)
    connection.execute("SAVEPOINT migrate_questionnaires")  # all or nothing, even outside a transaction
    try:
        connection.execute(QUESTIONNAIRES_DDL.replace(
            "CREATE TABLE IF NOT EXISTS questionnaires", "CREATE TABLE questionnaires_migrated"
        ))
        connection.execute(
            f"INSERT INTO questionnaires_migrated ({columns}) SELECT {columns} FROM questionnaires"
        )
        connection.execute("DROP TABLE questionnaires")
        connection.execute("ALTER TABLE questionnaires_migrated RENAME TO questionnaires")
    except BaseException:
        connection.execute("ROLLBACK TO migrate_questionnaires")
        connection.execute("RELEASE migrate_questionnaires")
        raise
    connection.execute("RELEASE migrate_questionnaires")


def create_session_tables(connection: sqlite3.Connection) -> None:
    """Create the session-plan tables if missing."""
    for ddl in SESSION_DDL:
        connection.execute(ddl)


def migrate_emg_chunks(connection: sqlite3.Connection) -> None:
    """Give a schema-4 store's ``emg_chunks`` the ``offset_v`` column (0: its codes had none)."""
    columns = {str(row[1]) for row in connection.execute("PRAGMA table_info(emg_chunks)")}
    if columns and "offset_v" not in columns:
        connection.execute("ALTER TABLE emg_chunks ADD COLUMN offset_v REAL NOT NULL DEFAULT 0.0")


def migrate_outcomes(connection: sqlite3.Connection) -> None:
    """Give an outcome table of a store before schema 6 its ``trial_id`` column (inside the caller's
    transaction; its rows keep NULL until the study is analysed again)."""
    columns = {row[1] for row in connection.execute("PRAGMA table_info(outcomes)")}
    if columns and "trial_id" not in columns:
        connection.execute("ALTER TABLE outcomes ADD COLUMN trial_id INTEGER")


def create_study_tables(connection: sqlite3.Connection) -> None:
    """Make or migrate every table beyond the trials (inside the caller's transaction), in the order
    the study store always has: older stores first gain the registry's columns, lose the paper-only
    CHECK on questionnaire conditions, gain each outcome's trial; then the missing tables are made
    and schema 4's EMG chunks gain ``offset_v``."""
    migrate_participants(connection)
    migrate_questionnaires(connection)
    migrate_outcomes(connection)
    for ddl in (EMG_CHUNKS_DDL, OUTCOMES_DDL, ARTIFACTS_DDL, *SESSION_DDL):
        connection.execute(ddl)
    migrate_emg_chunks(connection)
