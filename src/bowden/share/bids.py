"""``bowden export --bids``: a study store as a BIDS 1.11 dataset (EMG, motion, physio, events).

Every trial that holds samples is exported, one run per trial (:mod:`bowden.share.layout`): its sEMG
with the store's codes (:mod:`bowden.share.emg_file`), the IMU elevation as motion and every loop
signal as physio (:mod:`bowden.share.timeseries`), its events (:mod:`bowden.share.events`); the
participants, the questionnaires (``phenotype/``) and the dataset description beside them. The
official validator (``bids-validator-deno``) passes the result with zero errors
(tests/share/test_bids_validator.py).
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from bowden import __version__
from bowden.contracts import SIMULATED_BACKENDS, TRIAL_TIME
from bowden.errors import OutputFileError
from bowden.share import layout
from bowden.share.emg_run import EmgRunFacts, write_emg_run
from bowden.share.events import events_sidecar, trial_events
from bowden.share.sessions import SESSIONS_SIDECAR, session_level
from bowden.share.timeseries import (
    MOTION_CHANNELS,
    motion_sidecar,
    physio_sidecar,
    write_motion,
    write_physio,
)
from bowden.store.study_store import StudyStore


@dataclass(frozen=True)
class BidsExport:
    """What :func:`export_bids` wrote: the dataset's directory, its subjects and runs."""

    directory: Path
    subjects: int
    runs: int
    emg_runs: int
    sessions: bool = False  # whether the dataset has the ses- level


@dataclass(frozen=True, kw_only=True)
class BidsOptions:
    """What ``bowden export`` adds to the store: mains frequency, authors, licence, EMG manufacturer."""

    power_line_hz: float | None = None  # 50 or 60 where the EMG was recorded; n/a if None
    authors: tuple[str, ...] = ()
    license_id: str | None = None  # SPDX identifier (CC-BY-4.0, CC0-1.0, ...)
    manufacturer: str | None = None  # the EMG amplifier's maker, where the import did not record it


def export_bids(
    store: StudyStore, directory: str | Path, options: BidsOptions | None = None
) -> BidsExport:
    """Write the store as a BIDS dataset into ``directory`` (new, empty, or a previous bowden export).

    Raises
    ------
    StoreError
        ``directory`` holds something else, or participants whose labels clash.
    OutputFileError
        A file cannot be written (names it).
    """
    options = options or BidsOptions()
    out = Path(directory)
    layout.check_empty_target(out)
    trials = store.trial_table()
    with_samples = set(store.trials_with_samples())
    trials = trials[trials["id"].isin(with_samples)]
    labels = layout.subject_labels(sorted(trials["participant"].unique()))
    level = session_level(store, zip(trials["id"].astype(int), trials["participant"], strict=True))
    model = _stored_model(store)
    try:
        out.mkdir(parents=True, exist_ok=True)
        simulated = [_is_simulated(meta) for meta in trials["metadata"]]
        description = layout.dataset_description(
            __version__,
            simulated=bool(simulated) and all(simulated),
            source=store.path.name,
            authors=options.authors,
            license_id=options.license_id,
        )
        layout.write_json(out / "dataset_description.json", description)
        (out / "README.md").write_text(layout.README)
        layout.write_table(out / "participants.tsv", layout.participants_table(store.participants(), labels))
        layout.write_json(out / "participants.json", layout.PARTICIPANTS_SIDECAR)
        _write_phenotype(out, store.questionnaires(), labels)
        emg_runs = 0
        for participant, label in labels.items():
            rows = trials[trials["participant"] == participant]
            scans: dict[str | None, list[tuple[str, str]]] = {}
            for row in rows.itertuples():
                session = level.labels[int(str(row.id))]
                files = _export_trial(store, out, (label, session), row, model, options)
                emg_runs += any(name.startswith("emg/") for name, _ in files)
                scans.setdefault(session, []).extend(files)
            for session, files in scans.items():
                stem = f"sub-{label}" + (f"_ses-{session}" if session is not None else "")
                table = pd.DataFrame([{"filename": name, "acq_time": when} for name, when in files])
                layout.write_table(_subject_dir(out, label, session) / f"{stem}_scans.tsv", table)
            if level.used:
                sessions = out / f"sub-{label}" / f"sub-{label}_sessions"
                layout.write_table(sessions.with_suffix(".tsv"), level.tables[participant])
                layout.write_json(sessions.with_suffix(".json"), SESSIONS_SIDECAR)
    except OSError as error:
        raise OutputFileError(f"cannot write the BIDS export to {out}: {error.strerror or error}") from None
    return BidsExport(out, subjects=len(labels), runs=len(trials), emg_runs=emg_runs, sessions=level.used)


def _subject_dir(out: Path, label: str, session: str | None) -> Path:
    return out / f"sub-{label}" / (f"ses-{session}" if session is not None else "")


def _export_trial(
    store: StudyStore, out: Path, where: tuple[str, str | None], row: Any, model: Any, options: BidsOptions
) -> list[tuple[str, str]]:
    """One trial's files (``where``: subject label, session label or None); returns their names
    relative to the subject's (session's) directory with acq_time."""
    label, session = where
    trial_id = int(row.id)
    meta = json.loads(row.metadata)
    simulated = _is_simulated(meta)
    samples = store.trial_samples(trial_id)
    events = store.trial_events(trial_id)
    started, _ended = store.trial_times_utc(trial_id)
    when = layout.acq_time(started)
    support = store_support(meta, row)
    event_labels = {
        "condition": row.condition,
        "speed": row.speed if row.speed is not None else "n/a",
        "support": support,
        "stop_reason": row.stop_reason,
    }
    time = samples[TRIAL_TIME].to_numpy(dtype=np.float64)
    subject = _subject_dir(out, label, session)
    files: list[tuple[str, str]] = []

    codes = store.trial_emg_codes(trial_id)
    emg_start = next(iter(codes.values())).start_time_s if codes else float(time[0])
    if codes:
        folder = _folder(subject, "emg")
        stem = layout.run_stem(label, trial_id, session=session)
        facts = EmgRunFacts(
            power_line_hz=options.power_line_hz,
            simulated=simulated,
            manufacturer=options.manufacturer,
        )
        path, _written = write_emg_run(
            out, folder, stem, codes, start=pd.Timestamp(started).to_pydatetime(), facts=facts
        )
        _write_events(
            folder / f"{stem}_events", trial_events(samples, events, labels=event_labels, start_s=emg_start)
        )
        files.append((f"emg/{path.name}", when))

    folder = _folder(subject, "motion")
    stem = layout.run_stem(label, trial_id, session=session, tracksys=layout.TRACKING_SYSTEM)
    rates = write_motion(folder / f"{stem}_motion.tsv", samples)
    layout.write_json(
        folder / f"{stem}_motion.json", motion_sidecar(rates, task=layout.TASK, simulated=simulated)
    )
    layout.write_table(folder / f"{stem}_channels.tsv", MOTION_CHANNELS)
    _write_events(
        folder / f"{stem}_events", trial_events(samples, events, labels=event_labels, start_s=float(time[0]))
    )
    files.append((f"motion/{stem}_motion.tsv", when))

    folder = _folder(subject, "beh")
    stem = layout.run_stem(label, trial_id, session=session)
    physio = f"{stem}_recording-{layout.LOOP_RECORDING}_physio"
    write_physio(folder / f"{physio}.tsv.gz", samples)
    layout.write_json(
        folder / f"{physio}.json",
        physio_sidecar(
            time,
            start_time_s=float(time[0]) - emg_start,
            model=trial_model(meta, model),
        ),
    )
    _write_events(
        folder / f"{stem}_events", trial_events(samples, events, labels=event_labels, start_s=float(time[0]))
    )
    files.append((f"beh/{physio}.tsv.gz", when))
    return files


def trial_model(meta: dict[str, Any], stored: Any) -> Any:
    """The compensation model the trial's controller used, as its metadata recorded it (file, SHA-256,
    coefficients, compensation), with the store's ``model.json`` document when the SHA-256 is its."""
    keys = ("compensation", "model", "model_sha256", "model_coefficients")
    recorded = {key: meta[key] for key in keys if key in meta}
    if stored is None:
        return recorded or None
    text, document = stored
    if not recorded or meta.get("model_sha256") == hashlib.sha256(text.encode()).hexdigest():
        return {**recorded, "document": document}
    return recorded


def store_support(meta: dict[str, Any], row: Any) -> float | None:
    """The trial's support fraction, if the row or its metadata gives one."""
    value = getattr(row, "support", None)
    if value is None:
        value = meta.get("support")
    return None if value is None or (isinstance(value, float) and math.isnan(value)) else float(value)


def _write_events(stem: Path, table: pd.DataFrame) -> None:
    layout.write_table(stem.with_name(stem.name + ".tsv"), table)
    layout.write_json(stem.with_name(stem.name + ".json"), events_sidecar(table["trial_type"].unique()))


def _write_phenotype(out: Path, answers: pd.DataFrame, labels: dict[str, str]) -> None:
    tables = layout.phenotype_tables(answers, labels)
    if not tables:
        return
    folder = _folder(out, "phenotype")
    for name, (table, sidecar) in tables.items():
        layout.write_table(folder / f"{name}.tsv", table)
        layout.write_json(folder / f"{name}.json", sidecar)


def _folder(parent: Path, name: str) -> Path:
    folder = parent / name
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _stored_model(store: StudyStore) -> tuple[str, Any] | None:
    """The compensation model document the store keeps (``model.json``): its text and content, or None."""
    text = store.artifact("model.json")
    if text is None:
        return None
    try:
        return text, json.loads(text)
    except ValueError:
        return None


def _is_simulated(metadata: Any) -> bool:
    meta = json.loads(metadata) if isinstance(metadata, str) else metadata
    return isinstance(meta, dict) and meta.get("backend") in SIMULATED_BACKENDS
