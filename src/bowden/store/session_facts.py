"""What the analysis needs to know of the sessions a store holds, beyond its completed trials.

* the **participants** as registered (anthropometrics, arm side, hand load, age), for the report;
* the **session plans**: who, which order rule, the seed, the condition order, how far each got;
* the trials **set aside**: those a session marked ``stopped`` (stopped early, a fault, or left
  running by a server that died) or ``redone`` (the operator ran the step again), with the reason —
  the analysis leaves them out and names them;
* the trials **left open**: no end recorded (the recording was cut, e.g. a killed server), named too.

Plain SQL on the store's tables (:mod:`bowden.store.tables` lays them out); a
store written before these tables existed gets empty answers.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Final

import pandas as pd

from bowden.store.study_store import StudyStore

_PARTICIPANTS: Final = (
    "SELECT id AS participant, sex, height_m, mass_kg, arm_side, hand_load_kg, age_years FROM participants "
    "ORDER BY id"
)
_PLANS: Final = """
SELECT s.id AS session, s.participant, s.order_rule, s.seed, s.sequence, s.condition_order,
       (SELECT count(*) FROM plan_steps p WHERE p.session_id = s.id) AS planned,
       (SELECT count(DISTINCT t.position) FROM session_trials t
        WHERE t.session_id = s.id AND t.status = 'completed') AS done,
       (SELECT count(*) FROM plan_steps p WHERE p.session_id = s.id AND p.skip_reason IS NOT NULL
        AND NOT EXISTS (SELECT 1 FROM session_trials t WHERE t.session_id = s.id
                        AND t.position = p.position AND t.status = 'completed')) AS skipped
FROM sessions s ORDER BY s.id
"""


@dataclass(frozen=True)
class SessionFacts:
    """The sessions of a store as the analysis reads them."""

    participants: pd.DataFrame  # participant, sex, height_m, mass_kg, arm_side, hand_load_kg, age_years
    plans: pd.DataFrame  # session, participant, order_rule, seed, sequence, condition_order, progress
    set_aside: dict[int, str]  # trial id → why the analysis leaves it out
    left_open: dict[int, str]  # trial id → a description of the trial without an end


def session_facts(store: StudyStore) -> SessionFacts:
    """Read the registry, the plans and the trials to name from ``store``."""
    plans = store.read_sql(_PLANS)
    plans["condition_order"] = [" → ".join(json.loads(text)) for text in plans["condition_order"]]
    set_aside = {}
    for trial_id, status, reason in store.read_sql(
        "SELECT trial_id, status, reason FROM session_trials WHERE status IN ('stopped', 'redone') "
        "ORDER BY trial_id"
    ).itertuples(index=False, name=None):
        why = "redone by the operator" if status == "redone" else "stopped before its end"
        set_aside[int(trial_id)] = f"{why}: {reason}" if reason else why
    left_open = {
        int(trial_id): f"trial {trial_id} (participant {participant}, {condition}, {speed})"
        for trial_id, participant, condition, speed in store.read_sql(
            "SELECT id, participant, condition, speed FROM trials WHERE ended_utc IS NULL ORDER BY id"
        ).itertuples(index=False, name=None)
    }
    return SessionFacts(store.read_sql(_PARTICIPANTS), plans, set_aside, left_open)


def left_open_notes(facts: SessionFacts) -> list[str]:
    """One line per trial without an end: it is not analysed, and says so."""
    return [
        f"{text} left open: no end was recorded (the recording was cut off, e.g. a server killed "
        "mid-trial); its samples are kept in the store but not analysed"
        for text in facts.left_open.values()
    ]
