"""The participant registry: each wearer registered once, every trial refers to it.

The ``participants`` table of the study store holds the pseudonymous id (the one rule of
:func:`bowden.contracts.is_participant_id`), sex, height, mass, the assisted arm, the load held in the
hand and, optionally, the age in years — never a name. The console registers a participant once;
``bowden serve`` and ``bowden run --participant P07`` take the anthropometrics from here, so they are
never typed twice and cannot differ between trials.

Stores written before the registry lack the last four columns:
:func:`bowden.store.tables.migrate_participants` adds
them (NULL: not recorded), so older stores stay readable and gain the registry when next opened.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Final, Literal

from bowden.errors import ConflictError, ParameterError, RequestError
from bowden.model import Subject
from bowden.store.connection import connect
from bowden.store.participants import Registration, all_registrations, find_registration, insert_registration
from bowden.store.tables import migrate_participants
from bowden.web.validation import choice, integer_in, no_unknown_fields, number_in, participant_id

_FIELDS: Final = ("participant", "height_m", "mass_kg", "sex", "arm_side", "hand_load_kg", "age_years")

ArmSide = Literal["left", "right"]


@dataclass(frozen=True, kw_only=True)
class Participant:
    """A registered participant.

    ``arm_side`` and ``hand_load_kg`` are None only for participants of stores written before the
    registry (or by ``bowden run`` without them); the console always records both.
    """

    participant: str
    subject: Subject
    arm_side: ArmSide | None
    hand_load_kg: float | None
    age_years: int | None = None

    def to_json(self) -> dict[str, object]:
        return {
            "participant": self.participant,
            "height_m": self.subject.height_m,
            "mass_kg": self.subject.mass_kg,
            "sex": self.subject.sex,
            "arm_side": self.arm_side,
            "hand_load_kg": self.hand_load_kg,
            "age_years": self.age_years,
        }

    def differences(self, other: Participant) -> list[str]:
        """The fields in which ``other`` differs from this registration."""
        mine, theirs = self.to_json(), other.to_json()
        return [name for name in mine if mine[name] != theirs[name]]


def parse_participant(payload: Mapping[str, object]) -> Participant:
    """Validate a registration (the console's form).

    Raises
    ------
    RequestError
        Naming the first missing, unknown or out-of-range field.
    """
    data = dict(payload)
    no_unknown_fields(data, _FIELDS, "participant")
    for required in ("participant", "height_m", "mass_kg", "sex", "arm_side", "hand_load_kg"):
        if required not in data:
            raise RequestError(f"participant: the field {required!r} is missing")
    sex = choice(data["sex"], ("female", "male"), "sex")
    side = choice(data["arm_side"], ("left", "right"), "arm_side")
    age = data.get("age_years")
    try:
        subject = Subject(
            height_m=number_in(data["height_m"], 1.0, 2.3, "height_m"),
            mass_kg=number_in(data["mass_kg"], 25.0, 250.0, "mass_kg"),
            sex="female" if sex == "female" else "male",
        )
    except ParameterError as error:
        raise RequestError(str(error)) from None
    return Participant(
        participant=participant_id(data["participant"]),
        subject=subject,
        arm_side="left" if side == "left" else "right",
        hand_load_kg=number_in(data["hand_load_kg"], 0.0, 5.0, "hand_load_kg"),
        age_years=None if age in (None, "") else integer_in(age, 16, 100, "age_years"),
    )


def _row(row: Registration) -> Participant:
    ident, sex, height, mass, side, load, age = row
    return Participant(
        participant=str(ident),
        subject=Subject(height_m=float(height), mass_kg=float(mass),
                        sex="female" if sex == "female" else "male"),
        arm_side="left" if side == "left" else "right" if side == "right" else None,
        hand_load_kg=None if load is None else float(load),
        age_years=None if age is None else int(age),
    )


class Registry:
    """The participants table of a study-store file (created or migrated when opened)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        with connect(self.path) as connection, connection:
            migrate_participants(connection)

    def register(self, participant: Participant) -> bool:
        """Register ``participant``; return False if it was registered already with the same values.

        Raises
        ------
        ConflictError
            If the id is registered with other values (nothing is changed: a study's record is
            never overwritten by a retyped form).
        """
        known = self.find(participant.participant)
        if known is not None:
            differences = known.differences(participant)
            if not differences:
                return False
            raise ConflictError(
                f"{participant.participant} is registered already with other {', '.join(differences)}: "
                "nothing was changed (register a new id, or correct the registry by hand)"
            )
        stamp = datetime.now(UTC).isoformat(timespec="seconds")
        with connect(self.path) as connection, connection:
            insert_registration(
                connection,
                (participant.participant, participant.subject.sex, participant.subject.height_m,
                 participant.subject.mass_kg, participant.arm_side, participant.hand_load_kg,
                 participant.age_years),
                stamp,
            )
        return True

    def find(self, participant: str) -> Participant | None:
        with connect(self.path) as connection:
            row = find_registration(connection, participant)
        return None if row is None else _row(row)

    def get(self, participant: str) -> Participant:
        """The registration of ``participant``.

        Raises
        ------
        ConflictError
            If it is not registered (the message says how to register).
        """
        found = self.find(participant)
        if found is None:
            raise ConflictError(
                f"participant {participant} is not registered in {self.path}: register them once "
                "(console: Participant, or bowden run with --height/--mass/--sex)"
            )
        return found

    def all(self) -> list[Participant]:
        with connect(self.path) as connection:
            rows = all_registrations(connection)
        return [_row(row) for row in rows]
