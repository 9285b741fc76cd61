"""Session plans in the study store: the plan of each session and what became of each planned trial.

Tables (next to the runtime's ``trials``):

``sessions``
    one row per session: participant (registered), the protocol (JSON), the order rule, the seed it
    was drawn from, the participant's place among counterbalanced sessions, the condition order.
``plan_steps``
    one row per planned trial: session, position (from 1), condition, speed, repetitions, and the
    reason if the operator skipped it.
``session_trials``
    one row per trial started for a step: ``running`` until it ends, then ``completed`` (it ran its
    whole reference), ``stopped`` (stopped early, a fault, or left open by a server that died — kept,
    with the reason) or ``redone`` (completed, but the operator ran it again, with the reason).
``session_notes``
    the operator's decisions that have no trial of their own: a skipped step, a questionnaire taken
    for a condition not run (an exception), each with its reason and time.

A step's state is worked out from these rows, never stored twice: done if a trial of it completed,
running, skipped, or pending. So a server killed at any moment resumes from the store.
"""

from __future__ import annotations

import json
import secrets
import sqlite3
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Final

from bowden.errors import ConflictError, RequestError
from bowden.protocol.session_plan import PlanStep, StudyProtocol, condition_order, make_plan
from bowden.store.connection import connect
from bowden.store.tables import create_session_tables

LEFT_OPEN: Final = "left open: the server stopped during the trial (its samples up to then are kept)"
SET_ASIDE: Final = ("stopped", "redone")  # trials of a session that the analysis leaves out


def insert_note(
    connection: sqlite3.Connection, participant: str, condition: str | None, kind: str, reason: str,
    noted_utc: str, *, session_id: int | None = None, position: int | None = None,
) -> None:
    """Note an operator's decision without a trial of its own (inside the caller's transaction): a
    skipped step (``skip``), answers for a condition not run (``questionnaire_exception``)."""
    connection.execute(
        "INSERT INTO session_notes (session_id, participant, condition, position, kind, reason, "
        "noted_utc) VALUES (?, ?, ?, ?, ?, ?, ?)",
        (session_id, participant, condition, position, kind, reason, noted_utc),
    )


def session_protocols(connection: sqlite3.Connection) -> list[str]:
    """The protocol (JSON) of every stored session, oldest first."""
    return [str(row[0]) for row in connection.execute("SELECT protocol FROM sessions ORDER BY id")]


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


@dataclass(frozen=True, kw_only=True)
class StepState:
    """A planned trial and what became of it."""

    step: PlanStep
    state: str  # pending | running | done | skipped
    trial_id: int | None  # the completed (or running) trial
    attempts: tuple[tuple[int, str, str | None], ...]  # (trial id, status, reason) in order
    skip_reason: str | None


@dataclass(frozen=True, kw_only=True)
class Session:
    """A stored session and the state of its plan."""

    session_id: int
    participant: str
    protocol: StudyProtocol
    seed: int
    sequence: int
    order: tuple[str, ...]
    created_utc: str
    steps: tuple[StepState, ...]

    @property
    def next_step(self) -> StepState | None:
        return next((s for s in self.steps if s.state == "pending"), None)

    @property
    def running_step(self) -> StepState | None:
        return next((s for s in self.steps if s.state == "running"), None)

    def step(self, position: object) -> StepState:
        for state in self.steps:
            if state.step.position == position:
                return state
        raise RequestError(
            f"position: session {self.session_id} has no step {position!r} (1–{len(self.steps)})"
        )

    def finished_conditions(self) -> list[str]:
        """Conditions whose every step is done or skipped and at least one done, in plan order."""
        finished = []
        for condition in self.order:
            states = [s.state for s in self.steps if s.step.condition == condition]
            if states and all(s in ("done", "skipped") for s in states) and "done" in states:
                finished.append(condition)
        return finished


class SessionStore:
    """Sessions of a study-store file (tables created when opened).

    Opening it also closes the books on trials a stopped server left ``running``: they become
    ``stopped`` with :data:`LEFT_OPEN` as the reason, and their step is pending again.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        with connect(self.path) as connection, connection:
            create_session_tables(connection)
            connection.execute(
                "UPDATE session_trials SET status = 'stopped', reason = ?, updated_utc = ? "
                "WHERE status = 'running'",
                (LEFT_OPEN, _now()),
            )

    # --- making a session ------------------------------------------------------------------------
    def create(self, participant: str, protocol: StudyProtocol, *, seed: int | None = None) -> Session:
        """Plan and store a session for a registered participant (before any of its trials).

        ``seed`` (None: drawn now) is recorded with the plan. The Latin-square row is the number of
        counterbalanced sessions already in the store.

        Raises
        ------
        ConflictError
            If the participant has a session with trials still to run (resume it instead).
        """
        for existing in self.sessions(participant):
            if any(s.state in ("pending", "running") for s in existing.steps):
                raise ConflictError(
                    f"{participant} has an unfinished session ({existing.session_id}): resume it"
                )
        drawn = secrets.randbits(31) if seed is None else seed
        with connect(self.path) as connection, connection:
            sequence = int(connection.execute(
                "SELECT count(*) FROM sessions WHERE order_rule = ?", (protocol.order,)
            ).fetchone()[0])
            order = condition_order(protocol, seed=drawn, sequence=sequence)
            cursor = connection.execute(
                "INSERT INTO sessions (participant, protocol, order_rule, seed, sequence, condition_order, "
                "created_utc) VALUES (?, ?, ?, ?, ?, ?, ?)",
                (participant, json.dumps(protocol.to_json()), protocol.order, drawn, sequence,
                 json.dumps(list(order)), _now()),
            )
            session_id = int(cursor.lastrowid or 0)
            connection.executemany(
                "INSERT INTO plan_steps (session_id, position, condition, speed, repetitions) "
                "VALUES (?, ?, ?, ?, ?)",
                [(session_id, s.position, s.condition, s.speed, s.repetitions)
                 for s in make_plan(protocol, order)],
            )
        return self.get(session_id)

    # --- reading ---------------------------------------------------------------------------------
    def get(self, session_id: int) -> Session:
        with connect(self.path) as connection:
            return _read(connection, session_id)

    def sessions(self, participant: str | None = None) -> list[Session]:
        with connect(self.path) as connection:
            where, parameters = (" WHERE participant = ?", (participant,)) if participant else ("", ())
            rows = connection.execute(f"SELECT id FROM sessions{where} ORDER BY id", parameters)
            ids = [int(r[0]) for r in rows]
            return [_read(connection, i) for i in ids]

    def latest(self) -> Session | None:
        """The newest session (the one a console shows after a restart)."""
        with connect(self.path) as connection:
            row = connection.execute("SELECT max(id) FROM sessions").fetchone()
            return None if row[0] is None else _read(connection, int(row[0]))

    # --- trials of steps ---------------------------------------------------------------------------
    def trial_started(self, session_id: int, position: int, trial_id: int) -> None:
        with connect(self.path) as connection, connection:
            connection.execute(
                "INSERT INTO session_trials (trial_id, session_id, position, status, updated_utc) "
                "VALUES (?, ?, ?, 'running', ?)",
                (trial_id, session_id, position, _now()),
            )

    def trial_ended(self, trial_id: int, *, completed: bool, reason: str) -> bool:
        """Record how a step's trial ended; False if the trial belongs to no session."""
        status = "completed" if completed else "stopped"
        with connect(self.path) as connection, connection:
            cursor = connection.execute(
                "UPDATE session_trials SET status = ?, reason = ?, updated_utc = ? "
                "WHERE trial_id = ? AND status = 'running'",
                (status, None if completed else reason, _now(), trial_id),
            )
            return cursor.rowcount > 0

    def redo(self, session_id: int, position: int, reason: str) -> Session:
        """Run a step again: its completed (or last stopped) trial is kept and marked with ``reason``.

        Raises
        ------
        ConflictError
            If the step is running, or has no trial to redo.
        """
        state = self.get(session_id).step(position)
        if state.state == "running":
            raise ConflictError(f"step {position} is running: stop it first")
        if not state.attempts:
            raise ConflictError(f"step {position} has no trial to redo")
        if state.state == "done" and state.trial_id is not None:
            trial_id, status, text = state.trial_id, "redone", reason
        else:
            trial_id, status, old = state.attempts[-1]
            if status != "stopped" or state.state != "pending":
                raise ConflictError(f"step {position} is {state.state}: it has no trial left to redo")
            text = f"{reason} (stopped: {old})" if old else reason
        with connect(self.path) as connection, connection:
            connection.execute(
                "UPDATE session_trials SET status = ?, reason = ?, updated_utc = ? WHERE trial_id = ?",
                (status, text, _now(), trial_id),
            )
        return self.get(session_id)

    def skip(self, session_id: int, position: int, reason: str) -> Session:
        """Leave a pending step out, with ``reason`` (also noted in ``session_notes``)."""
        session = self.get(session_id)
        state = session.step(position)
        if state.state != "pending":
            raise ConflictError(f"step {position} is {state.state}: only a pending step can be skipped")
        with connect(self.path) as connection, connection:
            connection.execute(
                "UPDATE plan_steps SET skip_reason = ? WHERE session_id = ? AND position = ?",
                (reason, session_id, position),
            )
            insert_note(
                connection, session.participant, state.step.condition, "skip", reason, _now(),
                session_id=session_id, position=position,
            )
        return self.get(session_id)

    # --- questionnaires in their place -------------------------------------------------------------
    def has_plan(self, participant: str) -> bool:
        """Whether ``participant`` has a session plan (then only its trials count as run)."""
        with connect(self.path) as connection:
            row = connection.execute("SELECT count(*) FROM sessions WHERE participant = ?", (participant,))
            return bool(row.fetchone()[0])

    def has_run(self, participant: str, condition: str) -> bool:
        """Whether ``participant`` has run ``condition``: its questionnaires may be taken.

        With a session plan, only a completed trial of a step of ``condition`` counts: a training
        trial outside the plan is not the planned condition. Without one (trials of ``bowden run``
        or outside any plan), any trial of ``condition`` that ended counts.
        """
        planned = self.has_plan(participant)
        with connect(self.path) as connection:
            if planned:
                row = connection.execute(
                    "SELECT count(*) FROM session_trials s JOIN sessions x ON x.id = s.session_id "
                    "JOIN plan_steps p ON p.session_id = s.session_id AND p.position = s.position "
                    "WHERE x.participant = ? AND p.condition = ? AND s.status = 'completed'",
                    (participant, condition),
                ).fetchone()
            else:
                row = connection.execute(
                    "SELECT count(*) FROM trials WHERE participant = ? AND condition = ? "
                    "AND ended_utc IS NOT NULL",
                    (participant, condition),
                ).fetchone()
        return bool(row[0])

    def answered(self, participant: str) -> set[str]:
        """Conditions with stored questionnaires of ``participant``."""
        with connect(self.path) as connection:
            rows = connection.execute(
                "SELECT DISTINCT condition FROM questionnaires WHERE participant = ?", (participant,)
            ).fetchall()
        return {str(r[0]) for r in rows}

    def condition_end(self, session_id: int, condition: str) -> str | None:
        """When the last completed trial of a condition of the session ended (ISO 8601), if any."""
        with connect(self.path) as connection:
            row = connection.execute(
                "SELECT max(t.ended_utc) FROM session_trials s JOIN trials t ON t.id = s.trial_id "
                "JOIN plan_steps p ON p.session_id = s.session_id AND p.position = s.position "
                "WHERE s.session_id = ? AND p.condition = ? AND s.status = 'completed'",
                (session_id, condition),
            ).fetchone()
        return None if row[0] is None else str(row[0])


def _read(connection: sqlite3.Connection, session_id: int) -> Session:
    row = connection.execute(
        "SELECT participant, protocol, seed, sequence, condition_order, created_utc FROM sessions "
        "WHERE id = ?",
        (session_id,),
    ).fetchone()
    if row is None:
        raise RequestError(f"session: no session {session_id} in the store")
    participant, protocol, seed, sequence, order, created = row
    attempts: dict[int, list[tuple[int, str, str | None]]] = {}
    for trial_id, position, status, reason in connection.execute(
        "SELECT trial_id, position, status, reason FROM session_trials WHERE session_id = ? "
        "ORDER BY trial_id",
        (session_id,),
    ):
        attempts.setdefault(int(position), []).append((int(trial_id), str(status), reason))
    steps = []
    for position, condition, speed, repetitions, skip_reason in connection.execute(
        "SELECT position, condition, speed, repetitions, skip_reason FROM plan_steps WHERE session_id = ? "
        "ORDER BY position",
        (session_id,),
    ):
        tried = attempts.get(int(position), [])
        live = [t for t, status, _ in tried if status == "running"]
        done = [t for t, status, _ in tried if status == "completed"]
        state = "running" if live else "done" if done else "skipped" if skip_reason is not None else "pending"
        steps.append(StepState(
            step=PlanStep(position=int(position), condition=str(condition), speed=str(speed),
                          repetitions=int(repetitions)),
            state=state,
            trial_id=(live or done)[-1] if (live or done) else None,
            attempts=tuple(tried),
            skip_reason=skip_reason,
        ))
    return Session(
        session_id=session_id, participant=str(participant),
        protocol=StudyProtocol.from_json(json.loads(protocol)), seed=int(seed), sequence=int(sequence),
        order=tuple(json.loads(order)), created_utc=str(created), steps=tuple(steps),
    )
