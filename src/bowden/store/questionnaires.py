"""The ``questionnaires`` table's one writer and its reads.

The browser forms (:mod:`bowden.web.questionnaire_store`) store a participant's answers after a
condition as one submission, replacing a corrected one whole; the simulated study
(:mod:`bowden.store.study_store`) stores answers row by row, a repeated row replacing the stored one.
Rows are in :data:`~bowden.store.tables.QUESTIONNAIRE_COLUMNS` order. Writes run inside the caller's
transaction.
"""

from __future__ import annotations

import math
import sqlite3
from collections.abc import Iterable
from typing import Final

import numpy as np

from bowden.contracts import (
    BORG_HIGH,
    BORG_LOW,
    BORG_RPE_ITEM,
    FATIGUE_SITES,
    LIKERT_HIGH,
    LIKERT_LOW,
    NORDIC_SITES,
    PROTOCOL_NAME_RULE,
    QUESTIONNAIRE_BORG_RPE,
    QUESTIONNAIRE_FATIGUE,
    QUESTIONNAIRE_NORDIC,
    is_participant_id,
    is_protocol_name,
)
from bowden.errors import StoreError
from bowden.store.tables import QUESTIONNAIRE_COLUMNS

# The items and score range of each questionnaire (what the browser forms and the simulation write).
_QUESTIONNAIRE_ITEMS: Final = {
    QUESTIONNAIRE_NORDIC: (NORDIC_SITES, LIKERT_LOW, LIKERT_HIGH),
    QUESTIONNAIRE_BORG_RPE: ((BORG_RPE_ITEM,), BORG_LOW, BORG_HIGH),
    QUESTIONNAIRE_FATIGUE: (FATIGUE_SITES, LIKERT_LOW, LIKERT_HIGH),
}

# participant, condition, questionnaire, item, score, submitted_utc
Answer = tuple[str, str, str, str, int, str]

_INSERT: Final = f"INTO questionnaires ({', '.join(QUESTIONNAIRE_COLUMNS)}) VALUES (?, ?, ?, ?, ?, ?)"


def checked_answer(
    label: object, participant: object, condition: object, questionnaire: object, item: object, score: object
) -> tuple[str, str, str, str, int]:
    """One answer row of the simulated study, checked (the forms check theirs in
    :mod:`bowden.web.questionnaires`); a problem is a :class:`StoreError` naming the row (index label)."""
    where = f"questionnaire answers, row {label!r}"
    if not is_participant_id(participant):
        raise StoreError(
            f"{where}: participant {participant!r} is not a pseudonymous id (1–4 capital letters then "
            "1–4 digits, e.g. P07; never a name)"
        )
    if not is_protocol_name(condition):
        raise StoreError(f"{where}: condition {condition!r} is not a condition name ({PROTOCOL_NAME_RULE})")
    if questionnaire not in _QUESTIONNAIRE_ITEMS:
        raise StoreError(
            f"{where}: unknown questionnaire {questionnaire!r} (known: {', '.join(_QUESTIONNAIRE_ITEMS)})"
        )
    items, low, high = _QUESTIONNAIRE_ITEMS[str(questionnaire)]
    if item not in items:
        raise StoreError(f"{where}: {questionnaire} has no item {item!r} (items: {', '.join(items)})")
    if isinstance(score, bool | np.bool_) or not isinstance(score, int | float | np.integer | np.floating):
        raise StoreError(f"{where}: score {score!r} of {questionnaire}.{item} is not a number")
    if not math.isfinite(score):
        raise StoreError(f"{where}: score of {questionnaire}.{item} is missing ({score!r})")
    if not float(score).is_integer() or not low <= score <= high:
        raise StoreError(
            f"{where}: score {score!r} of {questionnaire}.{item} must be a whole number from {low} to {high}"
        )
    return str(participant), str(condition), str(questionnaire), str(item), int(score)


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
