"""The BIDS session level (``ses-``) of an export, from the sessions the store recorded.

A session is one plan run with a participant (:mod:`bowden.store.sessions`: ``session_trials`` ties
each trial started for a step to its session). BIDS makes the level optional: "if a participant has
only one session, the session level MAY be omitted" — and an export that uses it for one subject
should use it for all (bids-specification ``src/common-principles.md``, "Filesystem structure",
and the validator's ``INCONSISTENT_SUBJECTS`` check). So, consistently across the dataset:

- where any participant's exported trials come from more than one session, every trial goes under
  ``ses-<n>``: the participant's sessions numbered from 1 in the order they were made, and trials
  recorded outside any session plan (``bowden run`` without the console) under ``ses-unplanned``;
  each subject gets a ``_sessions.tsv`` (the session's start and its id in the store);
- otherwise (one session, or none, per participant: the simulated study, a single-visit lab study)
  no ``ses-`` level at all, as BIDS allows.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Final

import pandas as pd

from bowden.share.layout import acq_time
from bowden.store.study_store import StudyStore

UNPLANNED: Final = "unplanned"

SESSIONS_SIDECAR: Final[dict[str, Any]] = {
    "session_id": {"Description": "BIDS session label: the participant's sessions numbered from 1 in the "
                   "order they were planned; unplanned: trials recorded outside any session plan."},
    "acq_time": {"Description": "When the session was planned (UTC); its runs' start times are in the "
                 "scans files."},
    "bowden_session": {"Description": "The session's id in the bowden store (n/a: unplanned)."},
}


@dataclass(frozen=True)
class SessionLevel:
    """Each exported trial's session label (None everywhere when the level is omitted)."""

    labels: dict[int, str | None]
    tables: dict[str, pd.DataFrame]  # participant → its _sessions.tsv rows (empty when omitted)

    @property
    def used(self) -> bool:
        return bool(self.tables)


def session_level(store: StudyStore, trials: Iterable[tuple[int, str]]) -> SessionLevel:
    """The session level of the export of ``trials`` ((trial id, participant) pairs)."""
    pairs = list(trials)
    rows = store.trial_sessions()  # the store makes the session tables as it opens (empty in older ones)
    session_of = {
        int(trial): (int(session), str(created))
        for trial, session, created in rows.itertuples(index=False, name=None)
    }
    groups: dict[str, dict[int | None, str | None]] = {}
    for trial_id, participant in pairs:
        session, created = session_of.get(trial_id, (None, None))
        groups.setdefault(participant, {})[session] = created
    if all(len(sessions) <= 1 for sessions in groups.values()):
        return SessionLevel({trial_id: None for trial_id, _ in pairs}, {})
    labels: dict[int, str | None] = {}
    tables: dict[str, pd.DataFrame] = {}
    for participant, sessions in groups.items():
        planned = sorted(s for s in sessions if s is not None)
        label_of: dict[int | None, str] = {s: str(n) for n, s in enumerate(planned, start=1)}
        label_of[None] = UNPLANNED
        order = [*planned, *([None] if None in sessions else [])]
        tables[participant] = pd.DataFrame(
            {
                "session_id": [f"ses-{label_of[s]}" for s in order],
                "acq_time": ["n/a" if s is None else acq_time(str(sessions[s])) for s in order],
                "bowden_session": ["n/a" if s is None else s for s in order],
            }
        )
        for trial_id, owner in pairs:
            if owner == participant:
                labels[trial_id] = label_of[session_of.get(trial_id, (None, None))[0]]
    return SessionLevel(labels, tables)

