"""The ``questionnaires`` table's one writer and its reads.

The browser forms (:mod:`bowden.web.questionnaire_store`) store a participant's answers after a
condition as one submission, replacing a corrected one whole; the simulated study
(:mod:`bowden.store.study_store`) stores answers row by row, a repeated row replacing the stored one.
Rows are in :data:`~bowden.store.tables.QUESTIONNAIRE_COLUMNS` order. Writes run inside the caller's
transaction.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterable
from typing import Final

from bowden.store.tables import QUESTIONNAIRE_COLUMNS

# participant, condition, questionnaire, item, score, submitted_utc
Answer = tuple[str, str, str, str, int, str]

_INSERT: Final = f"INTO questionnaires ({', '.join(QUESTIONNAIRE_COLUMNS)}) VALUES (?, ?, ?, ?, ?, ?)"


def replace_submission(
    connection: sqlite3.Connection, participant: str, condition: str, answers: Iterable[Answer]
) -> None:
    """Make ``answers`` the participant's only answers after ``condition``."""
    connection.execute(
        "DELETE FROM questionnaires WHERE participant = ? AND condition = ?", (participant, condition)
    )
    connection.executemany(f"INSERT {_INSERT}", answers)


def upsert_answers(connection: sqlite3.Connection, answers: Iterable[Answer]) -> None:
    """Store answers, each replacing a stored answer to the same item (same participant, condition)."""
    connection.executemany(f"INSERT OR REPLACE {_INSERT}", answers)


def answer_count(connection: sqlite3.Connection, participant: str, condition: str) -> int:
    """How many answers of ``participant`` after ``condition`` are stored."""
    row = connection.execute(
        "SELECT count(*) FROM questionnaires WHERE participant = ? AND condition = ?",
        (participant, condition),
    ).fetchone()
    return int(row[0])


def answers(
    connection: sqlite3.Connection, participant: str | None = None, condition: str | None = None
) -> list[Answer]:
    """Stored answers, optionally of one participant and/or condition, in key order."""
    clauses, parameters = [], []
    if participant is not None:
        clauses.append("participant = ?")
        parameters.append(participant)
    if condition is not None:
        clauses.append("condition = ?")
        parameters.append(condition)
    where = f" WHERE {' AND '.join(clauses)}" if clauses else ""
    cursor = connection.execute(
        f"SELECT {', '.join(QUESTIONNAIRE_COLUMNS)} FROM questionnaires{where} "
        "ORDER BY participant, condition, questionnaire, item",
        parameters,
    )
    return [tuple(row) for row in cursor.fetchall()]


def submissions(connection: sqlite3.Connection) -> list[tuple[str, str, str]]:
    """``(participant, condition, submitted_utc)`` of every stored submission."""
    cursor = connection.execute(
        "SELECT participant, condition, max(submitted_utc) FROM questionnaires "
        "GROUP BY participant, condition ORDER BY participant, condition"
    )
    return [tuple(row) for row in cursor.fetchall()]
