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
from bowden.share.emg_file import emg_extension, write_emg_file
from bowden.share.emg_sidecars import CHANNELS_SIDECAR, channels_table, emg_sidecar
from bowden.share.events import EVENTS_SIDECAR, trial_events
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


def export_bids(
    store: StudyStore, directory: str | Path, *, power_line_hz: float | None = None
) -> BidsExport:
    """Write the store as a BIDS dataset into ``directory`` (new, empty, or a previous bowden export).

    ``power_line_hz`` is the mains frequency where the EMG was recorded (50 or 60), ``n/a`` if None.

    Raises
    ------
    StoreError
        ``directory`` holds something else, participants whose labels clash, EMG that EDF/BDF cannot
        hold without loss.
    OutputFileError
        A file cannot be written (names it).
    """
    out = Path(directory)
    layout.check_empty_target(out)
    trials = store.trial_table()
    with_samples = set(store.trials_with_samples())
    trials = trials[trials["id"].isin(with_samples)]
    labels = layout.subject_labels(sorted(trials["participant"].unique()))
    model = _stored_model(store)
    try:
        out.mkdir(parents=True, exist_ok=True)
        simulated = [_is_simulated(meta) for meta in trials["metadata"]]
        description = layout.dataset_description(
            __version__, simulated=bool(simulated) and all(simulated), source=store.path.name
        )
        layout.write_json(out / "dataset_description.json", description)
        (out / "README.md").write_text(layout.README)
        layout.write_table(out / "participants.tsv", layout.participants_table(store.participants(), labels))
        layout.write_json(out / "participants.json", layout.PARTICIPANTS_SIDECAR)
        _write_phenotype(out, store.questionnaires(), labels)
        emg_runs = 0
        for participant, label in labels.items():
            rows = trials[trials["participant"] == participant]
            scans = [_export_trial(store, out, label, row, model, power_line_hz) for row in rows.itertuples()]
            emg_runs += sum(1 for files in scans if any(name.startswith("emg/") for name, _ in files))
            table = pd.DataFrame(
                [{"filename": name, "acq_time": when} for files in scans for name, when in files]
            )
            layout.write_table(out / f"sub-{label}" / f"sub-{label}_scans.tsv", table)
    except OSError as error:
        raise OutputFileError(f"cannot write the BIDS export to {out}: {error.strerror or error}") from None
    return BidsExport(out, subjects=len(labels), runs=len(trials), emg_runs=emg_runs)


def _export_trial(
    store: StudyStore, out: Path, label: str, row: Any, model: Any, power_line_hz: float | None
) -> list[tuple[str, str]]:
    """One trial's files; returns their names relative to the subject directory with acq_time."""
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
    subject = out / f"sub-{label}"
    files: list[tuple[str, str]] = []

    codes = store.trial_emg_codes(trial_id)
    emg_start = next(iter(codes.values())).start_time_s if codes else float(time[0])
    if codes:
        folder = _folder(subject, "emg")
        stem = layout.run_stem(label, trial_id)
        path = folder / f"{stem}_emg{emg_extension(codes)}"
        written = write_emg_file(path, codes, start=pd.Timestamp(started).to_pydatetime())
        samples_n = next(iter(codes.values())).codes.size
        layout.write_json(
            folder / f"{stem}_emg.json",
            emg_sidecar(
                written,
                task=layout.TASK,
                duration_s=samples_n / written[0].rate_hz,
                power_line_hz=power_line_hz,
                simulated=simulated,
            ),
        )
        layout.write_table(folder / f"{stem}_channels.tsv", channels_table(written))
        layout.write_json(folder / f"{stem}_channels.json", CHANNELS_SIDECAR)
        _write_events(
            folder / f"{stem}_events", trial_events(samples, events, labels=event_labels, start_s=emg_start)
        )
        files.append((f"emg/{path.name}", when))

    folder = _folder(subject, "motion")
    stem = layout.run_stem(label, trial_id, tracksys=layout.TRACKING_SYSTEM)
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
    stem = layout.run_stem(label, trial_id)
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
    layout.write_json(stem.with_name(stem.name + ".json"), EVENTS_SIDECAR)


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
