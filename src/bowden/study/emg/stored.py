"""What the EMG import reads from and writes to a study store: sync events, imports, trial EMG.

A trial's sync events (:mod:`bowden.runtime.sync_events`) place it on the host clock; an event of
kind ``emg_import`` per trial says which file its EMG came from (JSON: file name, SHA-256, clock fit),
which makes a second import of the same file a no-op and lets the report name the source.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

import pandas as pd

from bowden.errors import RecordingError
from bowden.runtime.sync_events import SYNC_KIND, SyncEvent
from bowden.store.emg_chunks import EncodedEmgChunk
from bowden.store.study_store import StudyStore

EMG_IMPORT_KIND: Final = "emg_import"


@dataclass(frozen=True, kw_only=True)
class TrialSync:
    """A trial's start and end edges (host clock) and where its loop time zero lies on that clock."""

    trial_id: int
    start: SyncEvent
    end: SyncEvent
    last_sample_s: float  # loop time of the trial's last recorded cycle

    @property
    def zero_host_time_s(self) -> float:
        return self.start.zero_host_time_s


def trial_syncs(store: StudyStore) -> dict[int, TrialSync]:
    """The completed trials that carry both sync edges, by id (recording order).

    Raises
    ------
    RecordingError
        If a trial's sync event is malformed (names the trial).
    """
    completed = {trial.trial_id for trial in store.completed_trials()}
    edges: dict[int, dict[str, SyncEvent]] = {}
    for trial_id, time_s, message in store.events(SYNC_KIND).itertuples(index=False, name=None):
        if int(trial_id) not in completed:
            continue
        try:
            event = SyncEvent.from_event(None if pd.isna(time_s) else float(time_s), str(message))
        except RecordingError as error:
            raise RecordingError(f"trial {trial_id}: {error}") from None
        edges.setdefault(int(trial_id), {})[event.edge] = event
    last = store.last_sample_times()
    return {
        trial_id: TrialSync(
            trial_id=trial_id, start=pair["start"], end=pair["end"], last_sample_s=last.get(trial_id, 0.0)
        )
        for trial_id, pair in sorted(edges.items())
        if "start" in pair and "end" in pair
    }


def emg_imports(store: StudyStore) -> dict[int, dict[str, Any]]:
    """Per trial id, the provenance of its imported EMG (file, sha256, fit...)."""
    imports: dict[int, dict[str, Any]] = {}
    for trial_id, _time, message in store.events(EMG_IMPORT_KIND).itertuples(index=False, name=None):
        try:
            content = json.loads(message)
        except ValueError:
            continue
        if isinstance(content, dict):
            imports[int(trial_id)] = content
    return imports


def trials_with_emg(store: StudyStore) -> set[int]:
    return set(store.trials_with_emg())


def write_imported_emg(
    store: StudyStore,
    emg: Mapping[int, Sequence[EncodedEmgChunk]],
    provenance: Mapping[int, Mapping[str, Any]],
) -> None:
    """Store (or replace) the EMG of several trials with its provenance, in one transaction.

    ``emg`` holds each trial's chunks as :func:`~bowden.store.emg_chunks.encode_verified_emg` made and
    checked them. A trial's previous EMG and import events are replaced. Every trial is written, or none.
    """
    events = {
        trial_id: (EMG_IMPORT_KIND, json.dumps(dict(provenance[trial_id]), allow_nan=False))
        for trial_id in emg
    }
    store.replace_emg(emg, events)
