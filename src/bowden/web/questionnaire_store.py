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
one rebuilds the table with the name rule (:func:`bowden.store.tables.migrate_questionnaires`, every
answer kept). The table, its migration and its writes belong to :mod:`bowden.store`; this is the
browser forms' door to it (a second submission refused unless it replaces the first).

The file uses the runtime's connection settings (WAL, ``synchronous=FULL``), so questionnaires can be
written while a trial is being recorded into the same file.
"""

from __future__ import annotations

import sqlite3
from datetime import UTC, datetime
from pathlib import Path
from typing import Final

from bowden.errors import ConflictError, StoreError
from bowden.store.questionnaires import answer_count, answers, replace_submission, submissions
from bowden.store.schema import configure_connection, create_schema
from bowden.store.sessions import insert_note
from bowden.store.tables import QUESTIONNAIRE_COLUMNS, migrate_questionnaires
from bowden.web.questionnaires import QuestionnaireResponse

COLUMNS: Final = QUESTIONNAIRE_COLUMNS


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
        run, noted in ``session_notes`` (:mod:`bowden.store.sessions`) in the same transaction.

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
                existing = answer_count(connection, *key)
                if existing and not replace:
                    raise ConflictError(
                        f"answers of {response.participant} after {response.condition} are already "
                        "stored; tick 'replace' to correct them"
                    )
                replace_submission(connection, *key, rows)
                if exception is not None:
                    insert_note(connection, *key, "questionnaire_exception", exception, stamp)
        except sqlite3.Error as error:
            raise StoreError(f"cannot write questionnaires into {self.path}: {error}") from None
        return len(rows)

    def rows(
        self, participant: str | None = None, condition: str | None = None
    ) -> list[tuple[str, str, str, str, int, str]]:
        """Stored answers (``COLUMNS`` order), optionally of one participant and/or condition."""
        with self._connect() as connection:
            return answers(connection, participant, condition)

    def submissions(self) -> list[tuple[str, str, str]]:
        """``(participant, condition, submitted_utc)`` of every stored submission."""
        with self._connect() as connection:
            return submissions(connection)


class _Connection:
    """A connection that closes when its ``with`` block ends (sqlite3's own only ends a transaction)."""

    def __init__(self, connection: sqlite3.Connection) -> None:
        self.connection = connection

    def __enter__(self) -> sqlite3.Connection:
        return self.connection

    def __exit__(self, *exc: object) -> None:
        self.connection.close()
