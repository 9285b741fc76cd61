"""The console as the protocol: registered participants, their session plans, the next trial.

:class:`SessionDesk` joins the registry, the session store and the trial manager: it starts the
plan's next trial with the registered anthropometrics, records how each trial ended, and says what
the operator must do next (run the next trial, take the questionnaires, wait out the break).
Everything it knows is in the study store, so a restarted server shows the same state.
"""

from __future__ import annotations

import logging
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from bowden.errors import ConflictError, RequestError
from bowden.protocol.session_plan import StudyProtocol
from bowden.store.sessions import Session, SessionStore
from bowden.web.labels import condition_label
from bowden.web.live import ROLE_CONSOLE, LiveHub
from bowden.web.registry import Participant, Registry
from bowden.web.store_catalogue import checked_catalogue
from bowden.web.trial_setup import TrialSetup, condition_support, parse_setup
from bowden.web.trials import TrialManager

_log = logging.getLogger(__name__)
_ANTHROPOMETRICS = ("height_m", "mass_kg", "sex", "hand_load_kg")
DEFAULT_HAND_LOAD_KG = 0.5  # participants of older stores have none recorded (paper: 0.5 kg)


def reason_text(value: object, field: str = "reason") -> str:
    """A reason the operator gives (redo, skip, questionnaire exception): 3–300 printable characters."""
    if not isinstance(value, str) or not 3 <= len(value.strip()) <= 300 or not value.isprintable():
        raise RequestError(f"{field}: say why in 3–300 characters (one line)")
    return value.strip()


class SessionDesk:
    """Sessions of one server.

    Parameters
    ----------
    store_path
        The study store.
    manager
        Runs the trials (its end messages update the plan).
    protocol
        The protocol new sessions follow.

    Raises
    ------
    ParameterError
        If the protocol defines a condition or speed the store knows with another meaning.
    """

    def __init__(self, store_path: Path, manager: TrialManager, protocol: StudyProtocol) -> None:
        self.registry = Registry(store_path)
        self.store = SessionStore(store_path)  # trials a dead server left running become stopped
        self.manager = manager
        self.hub: LiveHub = manager.hub
        self.protocol = protocol
        # The names trials and questionnaires outside a plan may use: the protocol's and the store's.
        self.catalogue = checked_catalogue(store_path, protocol.catalogue)
        latest = self.store.latest()
        self.current: int | None = None if latest is None else latest.session_id
        manager.finished_listeners.append(self._trial_ended)

    # --- sessions --------------------------------------------------------------------------------
    def open(self, participant: str, *, seed: int | None = None) -> tuple[Session, bool]:
        """The participant's unfinished session, or a new one planned now; and whether it is new."""
        self.registry.get(participant)  # registered first
        for session in reversed(self.store.sessions(participant)):
            if any(s.state in ("pending", "running") for s in session.steps):
                self.current = session.session_id
                return session, False
        session = self.store.create(participant, self.protocol, seed=seed)
        self.current = session.session_id
        _log.info("session %s planned for %s: %s (seed %s)", session.session_id, participant,
                  ", ".join(session.order), session.seed)
        return session, True

    async def start_next(self, session_id: int) -> dict[str, object]:
        """Start the next pending trial of the plan; return the trial's status."""
        session = self.store.get(session_id)
        if self.manager.running:
            raise ConflictError("a trial is running: stop it before starting another")
        state = session.next_step
        if state is None:
            raise ConflictError(f"session {session_id} has no trial left to run")
        participant = self.registry.get(session.participant)
        step = state.step
        catalogue = session.protocol.catalogue  # the plan's own, as stored with it
        setup = TrialSetup(
            participant=participant.participant,
            condition=step.condition,
            speed=step.speed,
            speed_peak_deg_s=catalogue.peak_deg_s(step.speed),
            support=condition_support(step.condition, catalogue),
            repetitions=step.repetitions,
            lead_in_s=session.protocol.lead_in_s,
            subject=participant.subject,
            hand_load_kg=_hand_load(participant),
        )
        status = await self.manager.start(setup, metadata={
            "session_id": session_id, "plan_position": step.position, "plan_seed": session.seed,
            "arm_side": participant.arm_side,
        })
        # No await between the start and this row: the trial's end is handled after it.
        self.store.trial_started(session_id, step.position, int(status["trial_id"]))  # type: ignore[call-overload]
        self.current = session_id
        self.publish(session_id)
        return status

    def redo(self, session_id: int, position: int, reason: str) -> dict[str, Any]:
        self.store.redo(session_id, position, reason)
        return self.publish(session_id)

    def skip(self, session_id: int, position: int, reason: str) -> dict[str, Any]:
        self.store.skip(session_id, position, reason)
        return self.publish(session_id)

    def _trial_ended(self, result: dict[str, object]) -> None:
        trial_id = result.get("trial_id")
        if not isinstance(trial_id, int):
            return
        ended = self.store.trial_ended(
            trial_id, completed=bool(result.get("completed")), reason=str(result["reason"])
        )
        if ended and self.current is not None:
            self.publish(self.current)

    def registered_setup(self, payload: dict[str, object]) -> tuple[TrialSetup, Participant | None]:
        """A trial outside any plan (``/api/trial/start``), with the registry's anthropometrics.

        A registered participant's height, mass, sex and hand load come from the registry; given
        again they must agree with it. For an unregistered one the registration made from the
        request (arm side not recorded) is returned too: the caller registers it once the trial has
        started (a refused start changes nothing), so every trial refers to the registry.
        """
        ident = payload.get("participant")
        known = self.registry.find(ident) if isinstance(ident, str) else None
        if known is not None:
            registered = known.to_json()
            payload = {**{k: registered[k] for k in _ANTHROPOMETRICS if registered[k] is not None}, **payload}
        setup = parse_setup(payload, self.catalogue)
        if known is None:
            return setup, Participant(participant=setup.participant, subject=setup.subject,
                                      arm_side=None, hand_load_kg=setup.hand_load_kg)
        given = {"height_m": setup.subject.height_m, "mass_kg": setup.subject.mass_kg,
                 "sex": setup.subject.sex, "hand_load_kg": setup.hand_load_kg}
        registered = known.to_json()
        for name, value in given.items():
            if registered[name] is not None and registered[name] != value:
                raise RequestError(
                    f"{name}: {setup.participant} is registered with {registered[name]}, not {value} "
                    "(the registry's values are used; leave the field out)"
                )
        return setup, None

    # --- questionnaires in their place -----------------------------------------------------------
    def check_questionnaire(self, participant: str, condition: str, exception: object) -> str | None:
        """Refuse questionnaires for a condition the participant has not run, unless excepted.

        Returns the exception's reason (None: the condition was run), which the questionnaire store
        records in the same transaction as the answers (so a refused submission leaves no note).
        """
        if self.store.has_run(participant, condition):
            if exception not in (None, ""):
                raise RequestError("exception: only for a condition not run (this one was run)")
            return None
        if exception in (None, ""):
            where = (" in the session plan (a trial outside the plan does not count)"
                     if self.store.has_plan(participant) else "")
            raise ConflictError(
                f"{participant} has not run {condition}{where}: questionnaires come after the condition's "
                "trials (mark an exception with a reason to store them anyway)"
            )
        return reason_text(exception, "exception")

    # --- status ----------------------------------------------------------------------------------
    def publish(self, session_id: int) -> dict[str, Any]:
        """Send the session's status to the consoles; return it."""
        status = self.status(self.store.get(session_id))
        self.hub.publish(status, (ROLE_CONSOLE,))
        return status

    def status(self, session: Session) -> dict[str, Any]:
        """What the console shows: the plan, what is next, progress, questionnaires due, the break."""
        participant = self.registry.find(session.participant)
        steps = [
            {
                "position": s.step.position, "condition": s.step.condition,
                "label": condition_label(s.step.condition), "speed": s.step.speed,
                "repetitions": s.step.repetitions, "state": s.state, "trial_id": s.trial_id,
                "skip_reason": s.skip_reason,
                "attempts": [{"trial_id": t, "status": st, "reason": r} for t, st, r in s.attempts],
            }
            for s in session.steps
        ]
        answered = self.store.answered(session.participant)
        finished = session.finished_conditions()
        due = next((c for c in finished if c not in answered), None)
        next_step, running = session.next_step, session.running_step
        counts = {state: sum(1 for s in session.steps if s.state == state) for state in ("done", "skipped")}
        return {
            "type": "session",
            "session_id": session.session_id,
            "participant": (
                participant.to_json() if participant is not None else {"participant": session.participant}
            ),
            "seed": session.seed,
            "order_rule": session.protocol.order,
            "sequence": session.sequence,
            "condition_order": list(session.order),
            "protocol": session.protocol.to_json(),
            "steps": steps,
            "next": None if next_step is None else next_step.step.position,
            "running": None if running is None else running.step.position,
            "progress": {**counts, "total": len(session.steps)},
            "questionnaires_answered": [c for c in session.order if c in answered],
            "questionnaire_due": due,
            "break": self._break(session, finished),
            "finished": next_step is None and running is None,
        }

    def _break(self, session: Session, finished: list[str]) -> dict[str, object] | None:
        """The break after the latest finished condition, while the next trial is of another one."""
        if not finished or session.running_step is not None:
            return None
        condition = finished[-1]
        following = session.next_step
        if following is not None and following.step.condition == condition:
            return None
        if following is not None and following.step.position < max(
            s.step.position for s in session.steps if s.step.condition == condition
        ):
            return None  # a skipped-over trial of an earlier condition: no break yet
        ended = self.store.condition_end(session.session_id, condition)
        if ended is None:
            return None
        elapsed = (datetime.now(UTC) - datetime.fromisoformat(ended)).total_seconds()
        return {"condition": condition, "ended_utc": ended, "elapsed_s": max(0.0, elapsed),
                "length_s": session.protocol.break_s}


def _hand_load(participant: Participant) -> float:
    return DEFAULT_HAND_LOAD_KG if participant.hand_load_kg is None else participant.hand_load_kg
