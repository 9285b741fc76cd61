"""The ``questionnaires`` table of the study store (SQLite, next to the runtime's trials and samples).

One row per answered item, in the long format the analysis reads::

    participant TEXT   pseudonymous id (P01), never a name (contracts.is_participant_id, checked
                       again by the database)
    condition   TEXT   a condition name by contracts.is_protocol_name (the paper's or a lab's own)
    questionnaire TEXT nordic | borg_rpe | fatigue
    item        TEXT   site name (nordic, fatigue) or "rpe"
    score       INTEGER 1–7 (nordic, fatigue) or 6–20 (borg_rpe)
    submitted_utc TEXT ISO 8601

keyed by ``(participant, condition, questionnaire, item)``. A submission writes all of a participant's
answers for a condition in one transaction: either every item is stored or none is. A second
submission for the same participant and condition is refused unless it explicitly replaces the first
(a typo can be corrected, an accidental double submission cannot silently overwrite).

Stores written before custom protocols limited ``condition`` to the paper's four by a CHECK; opening
one rebuilds the table with the name rule (:func:`migrate_questionnaires`, every answer kept).

The file uses the runtime's connection settings (WAL, ``synchronous=FULL``), so questionnaires can be
written while a trial is being recorded into the same file.
"""

from __future__ import annotations

import sqlite3
from datetime import UTC, datetime
from pathlib import Path
from typing import Final

from bowden.contracts import QUESTIONNAIRES
from bowden.errors import ConflictError, StoreError
from bowden.runtime.store_schema import configure_connection, create_schema
from bowden.web.questionnaires import (
    BORG_HIGH,
    BORG_LOW,
    BORG_RPE,
    LIKERT_HIGH,
    LIKERT_LOW,
    QuestionnaireResponse,
)

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
        CASE questionnaire WHEN '{BORG_RPE}' THEN score BETWEEN {BORG_LOW} AND {BORG_HIGH}
        ELSE score BETWEEN {LIKERT_LOW} AND {LIKERT_HIGH} END),
    submitted_utc TEXT NOT NULL,
    PRIMARY KEY (participant, condition, questionnaire, item)
) STRICT
"""

COLUMNS: Final = ("participant", "condition", "questionnaire", "item", "score", "submitted_utc")
# The CHECK of stores written before custom protocols: the paper's four conditions only.
_PAPER_ONLY_CHECK: Final = "CHECK (condition IN ("


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
    columns = ", ".join(COLUMNS)
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


class QuestionnaireStore:
    """Reads and writes questionnaire answers in a study-store file.

    Parameters
    ----------
    path
        The SQLite study store (created if missing).

    Raises
    ------
    StoreError
        If the file cannot be opened or is not a bowden store of a version this bowden knows (checked
        here, so ``bowden serve`` refuses such a store at start-up, before serving anything, with
        the runtime's own check; the file is then left unchanged).
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            with self._connect() as connection, connection:
                create_schema(connection)  # the version stamp and the trial tables, as the recorder's
                migrate_questionnaires(connection)
        except sqlite3.Error as error:
            raise StoreError(f"cannot open the study store {self.path}: {error}") from None

    def _connect(self) -> _Connection:
        try:
            connection = sqlite3.connect(self.path, timeout=5.0)
        except sqlite3.Error as error:
            raise StoreError(f"cannot open the study store {self.path}: {error}") from None
        try:
            configure_connection(connection)
        except sqlite3.Error as error:
            connection.close()
            raise StoreError(f"cannot open the study store {self.path}: {error}") from None
        except BaseException:
            connection.close()  # a refused file (StoreError) is not kept open
            raise
        return _Connection(connection)

    def save(
        self, response: QuestionnaireResponse, *, replace: bool = False, exception: str | None = None
    ) -> int:
        """Store every answer of ``response`` in one transaction; return the number of rows written.

        ``exception``: the operator's reason for answers after a condition the participant did not
        run, noted in ``session_notes`` (:mod:`bowden.web.session_store`) in the same transaction.

        Raises
        ------
        ConflictError
            If answers for the participant and condition exist and ``replace`` is False (nothing
            is written then).
        StoreError
            If the file cannot be written (nothing is written then).
        """
        stamp = datetime.now(UTC).isoformat(timespec="seconds")
        rows = [
            (response.participant, response.condition, questionnaire, item, score, stamp)
            for questionnaire, item, score in response.items()
        ]
        key = (response.participant, response.condition)
        try:
            with self._connect() as connection, connection:
                existing = connection.execute(
                    "SELECT count(*) FROM questionnaires WHERE participant = ? AND condition = ?", key
                ).fetchone()[0]
                if existing and not replace:
                    raise ConflictError(
                        f"answers of {response.participant} after {response.condition} are already "
                        "stored; tick 'replace' to correct them"
                    )
                connection.execute(
                    "DELETE FROM questionnaires WHERE participant = ? AND condition = ?", key
                )
                connection.executemany(
                    f"INSERT INTO questionnaires ({', '.join(COLUMNS)}) VALUES (?, ?, ?, ?, ?, ?)", rows
                )
                if exception is not None:
                    connection.execute(
                        "INSERT INTO session_notes (participant, condition, kind, reason, noted_utc) "
                        "VALUES (?, ?, 'questionnaire_exception', ?, ?)",
                        (*key, exception, stamp),
                    )
        except sqlite3.Error as error:
            raise StoreError(f"cannot write questionnaires into {self.path}: {error}") from None
        return len(rows)

    def rows(
        self, participant: str | None = None, condition: str | None = None
    ) -> list[tuple[str, str, str, str, int, str]]:
        """Stored answers (``COLUMNS`` order), optionally of one participant and/or condition."""
        clauses, parameters = [], []
        if participant is not None:
            clauses.append("participant = ?")
            parameters.append(participant)
        if condition is not None:
            clauses.append("condition = ?")
            parameters.append(condition)
        where = f" WHERE {' AND '.join(clauses)}" if clauses else ""
        with self._connect() as connection:
            cursor = connection.execute(
                f"SELECT {', '.join(COLUMNS)} FROM questionnaires{where} "
                "ORDER BY participant, condition, questionnaire, item",
                parameters,
            )
            return [tuple(row) for row in cursor.fetchall()]

    def submissions(self) -> list[tuple[str, str, str]]:
        """``(participant, condition, submitted_utc)`` of every stored submission."""
        with self._connect() as connection:
            cursor = connection.execute(
                "SELECT participant, condition, max(submitted_utc) FROM questionnaires "
                "GROUP BY participant, condition ORDER BY participant, condition"
            )
            return [tuple(row) for row in cursor.fetchall()]


class _Connection:
    """A connection that closes when its ``with`` block ends (sqlite3's own only ends a transaction)."""

    def __init__(self, connection: sqlite3.Connection) -> None:
        self.connection = connection

    def __enter__(self) -> sqlite3.Connection:
        return self.connection

    def __exit__(self, *exc: object) -> None:
        self.connection.close()
