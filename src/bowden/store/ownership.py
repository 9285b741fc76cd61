"""What in a study directory ``bowden study`` wrote itself: the trials of its store, read without
changing the file, and the files beside it.

``bowden study`` resumes in its ``--out`` directory: it skips the trials already stored and drops any
a crash left unfinished. It may do so only with its own trials; a store that also holds a recording
from the suit (``bowden run --record``, ``bowden serve``) is somebody's data, to be neither deleted
nor mixed with a virtual cohort.

The pipeline marks its trials with ``metadata["recorded_by"] = "bowden study"`` and a simulated
backend (``contracts.SIMULATED_BACKENDS``). Stores written before the mark existed say
``"backend": "simulation"``, a name only the pipeline ever wrote (``bowden run`` and ``bowden serve``
write ``"sim"`` or ``"can"``).

The files it writes beside the store (``bench.parquet``, ``model.json``, ``report.html``) are listed
with their SHA-256 in :data:`FILES_MANIFEST` as they are written. Only a file whose content is still
what the list says is the pipeline's to replace (``--force``) or to resume from; a lab's own
``model.json`` copied into the directory, or the pipeline's edited since, is somebody's. A directory
from before the list (``settings.json`` but no list) counts its files as the pipeline's, as then.
"""

from __future__ import annotations

import hashlib
import json
import sqlite3
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from bowden._atomic_file import write_text_atomically
from bowden.contracts import SIMULATED_BACKENDS
from bowden.errors import OutputFileError, StoreError

RECORDED_BY_KEY: Final = "recorded_by"
STUDY_PIPELINE: Final = "bowden study"
# The files bowden study wrote in its directory, with their SHA-256: {"files": {name: hex}}.
FILES_MANIFEST: Final = "bowden-study-files.json"
# The file whose presence marks a study directory of a version before the manifest.
_SETTINGS_FILE: Final = "settings.json"
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


def file_sha256(path: Path) -> str:
    """The SHA-256 of a file's bytes, in hex."""
    digest = hashlib.sha256()
    with path.open("rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def files_not_written_by_study(directory: Path, names: Iterable[str]) -> list[str]:
    """Which of ``names`` in ``directory`` are not as ``bowden study`` wrote them, each with why.

    Raises
    ------
    StoreError
        The manifest cannot be read.
    """
    written = _read_manifest(directory)
    problems = []
    for name in names:
        path = directory / name
        if not path.is_file():
            if path.exists():
                problems.append(f"{name} (not a file)")
            continue
        if written is None:  # a directory from before the manifest: its settings.json vouches
            if not (directory / _SETTINGS_FILE).is_file():
                problems.append(f"{name} (not written by bowden study)")
        elif name not in written:
            problems.append(f"{name} (not written by bowden study)")
        elif written[name] != file_sha256(path):
            problems.append(f"{name} (changed since bowden study wrote it)")
    return problems


def note_written(directory: Path, names: Iterable[str]) -> None:
    """Record ``names`` in ``directory`` as ``bowden study`` wrote them, as they are now (a name
    that is missing is left out of the manifest).

    Raises
    ------
    OutputFileError
        The manifest cannot be written.
    """
    written = _read_manifest(directory) or {}
    for name in names:
        path = directory / name
        if path.is_file():
            written[name] = file_sha256(path)
        else:
            written.pop(name, None)
    manifest = directory / FILES_MANIFEST
    text = json.dumps({"files": dict(sorted(written.items()))}, indent=2) + "\n"
    try:
        write_text_atomically(manifest, text)
    except OSError as error:
        raise OutputFileError(f"cannot write {manifest}: {error.strerror or error}") from None


def _read_manifest(directory: Path) -> dict[str, str] | None:
    """The manifest's files and hashes; None if there is no manifest."""
    path = directory / FILES_MANIFEST
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise StoreError(f"cannot read {path} ({error}): bowden study cannot tell its files from "
                         "others; use another --out directory") from None
    files = data.get("files") if isinstance(data, dict) else None
    if not isinstance(files, dict) or not all(isinstance(v, str) for v in files.values()):
        raise StoreError(f"{path} is damaged (no files object): bowden study cannot tell its files from "
                         "others; use another --out directory")
    return {str(name): value for name, value in files.items()}
