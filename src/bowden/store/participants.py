"""The ``participants`` table's one writer and its reads (the registry of :mod:`bowden.web.registry`
and the study store's virtual cohort write the same rows through here).

A participant is a pseudonymous id (:func:`bowden.contracts.is_participant_id`) with sex, height and
mass; the registry adds the assisted arm, the load in the hand, the age and when it was registered,
the study store a JSON ``metadata`` object. Every function runs inside the caller's transaction.
"""

from __future__ import annotations

import sqlite3
from typing import Final

# (id, sex, height_m, mass_kg, arm_side, hand_load_kg, age_years) of a registration.
Registration = tuple[str, str, float, float, str | None, float | None, int | None]

_SELECT_REGISTRATION: Final = (
    "SELECT id, sex, height_m, mass_kg, arm_side, hand_load_kg, age_years FROM participants"
)


def insert_registration(connection: sqlite3.Connection, row: Registration, registered_utc: str) -> None:
    """Register a participant (the id must be new: a registration is never overwritten)."""
    connection.execute(
        "INSERT INTO participants (id, sex, height_m, mass_kg, arm_side, hand_load_kg, age_years, "
        "registered_utc) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
        (*row, registered_utc),
    )


def upsert_anthropometrics(
    connection: sqlite3.Connection, participant: str, *, sex: str, height_m: float, mass_kg: float,
    metadata_json: str,
) -> None:
    """Insert a participant, or update the sex, height, mass and metadata of a known one (the
    registry's arm, load, age and time are left as they are)."""
    connection.execute(
        "INSERT INTO participants (id, sex, height_m, mass_kg, metadata) VALUES (?, ?, ?, ?, ?) "
        "ON CONFLICT(id) DO UPDATE SET sex=excluded.sex, height_m=excluded.height_m, "
        "mass_kg=excluded.mass_kg, metadata=excluded.metadata",
        (participant, sex, height_m, mass_kg, metadata_json),
    )


def find_registration(connection: sqlite3.Connection, participant: str) -> Registration | None:
    row = connection.execute(f"{_SELECT_REGISTRATION} WHERE id = ?", (participant,)).fetchone()
    return None if row is None else tuple(row)


def all_registrations(connection: sqlite3.Connection) -> list[Registration]:
    return [tuple(row) for row in connection.execute(f"{_SELECT_REGISTRATION} ORDER BY id")]
