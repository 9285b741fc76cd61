"""Which trials of a study store ``bowden study`` recorded itself, read without changing the file.

``bowden study`` resumes in its ``--out`` directory: it skips the trials already stored and drops any
a crash left unfinished. It may do so only with its own trials; a store that also holds a recording
from the suit (``bowden run --record``, ``bowden serve``) is somebody's data, to be neither deleted
nor mixed with a virtual cohort.

The pipeline marks its trials with ``metadata["recorded_by"] = "bowden study"`` and a simulated
backend (``contracts.SIMULATED_BACKENDS``). Stores written before the mark existed say
``"backend": "simulation"``, a name only the pipeline ever wrote (``bowden run`` and ``bowden serve``
write ``"sim"`` or ``"can"``).
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from bowden.contracts import SIMULATED_BACKENDS
from bowden.errors import StoreError

RECORDED_BY_KEY: Final = "recorded_by"
STUDY_PIPELINE: Final = "bowden study"
# The backend name of the pipeline's trials before they carried RECORDED_BY_KEY.
_PIPELINE_BACKEND_BEFORE_THE_MARK: Final = "simulation"


def made_by_study_pipeline(metadata: Mapping[str, Any]) -> bool:
    """Whether a trial's metadata says that ``bowden study`` simulated and stored it."""
    backend = metadata.get("backend")
    if backend not in SIMULATED_BACKENDS:
        return False
    marked = metadata.get(RECORDED_BY_KEY) == STUDY_PIPELINE
    return marked or (RECORDED_BY_KEY not in metadata and backend == _PIPELINE_BACKEND_BEFORE_THE_MARK)


@dataclass(frozen=True)
class TrialOrigins:
    """The trials of a store file: how many, and a description of each not made by the pipeline."""

    n_trials: int
    foreign: tuple[str, ...]


def read_trial_origins(path: str | Path) -> TrialOrigins:
    """Count a store's trials and describe those ``bowden study`` did not record (read-only).

    A missing or empty file holds no trials. Raises :class:`StoreError` if ``path`` is not a SQLite
    database or is one without bowden's ``trials`` table (another program's file).
    """
    path = Path(path)
    if not path.exists() or path.stat().st_size == 0:
        return TrialOrigins(n_trials=0, foreign=())
    try:
        # Not mode=ro: a read-only connection to a WAL store leaves -wal and -shm files behind, which
        # the last ordinary connection removes on closing. query_only keeps this one from writing.
        db = sqlite3.connect(path)
    except sqlite3.Error as error:
        raise StoreError(f"cannot open {path} to check its trials: {error}") from None
    try:
        db.execute("PRAGMA query_only = ON")
        tables = {row[0] for row in db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        if "trials" not in tables:
            if tables:
                raise StoreError(f"{path} is not a bowden study store (it has no trials table)")
            return TrialOrigins(n_trials=0, foreign=())
        rows = db.execute("SELECT id, participant, ended_utc, metadata FROM trials ORDER BY id").fetchall()
    except sqlite3.Error as error:
        raise StoreError(f"{path} is not a bowden study store: {error}") from None
    finally:
        db.close()
    foreign = tuple(
        _describe(trial_id, participant, ended_utc, metadata)
        for trial_id, participant, ended_utc, metadata in rows
        if not made_by_study_pipeline(metadata_object(metadata))
    )
    return TrialOrigins(n_trials=len(rows), foreign=foreign)


def metadata_object(text: object) -> dict[str, Any]:
    """A trial's ``metadata`` column as a dictionary (empty if it is not a JSON object)."""
    try:
        value = json.loads(str(text))
    except ValueError:
        return {}
    return value if isinstance(value, dict) else {}


def _describe(trial_id: int, participant: str, ended_utc: str | None, metadata: object) -> str:
    backend = metadata_object(metadata).get("backend", "not recorded")
    state = "unfinished" if ended_utc is None else "finished"
    return f"trial {trial_id} of {participant}, backend {backend!r}, {state}"
