"""BIDS names and the dataset's own files: description, README, participants, questionnaires, scans.

Layout (BIDS 1.11; bids-specification ``src/common-principles.md``, "Filesystem structure")::

    dataset_description.json  README.md  participants.tsv/.json  phenotype/<questionnaire>.tsv/.json
    sub-<participant>/sub-<participant>_scans.tsv
    sub-<participant>/emg/sub-<p>_task-armelevation_run-<trial>_emg.edf (.json, _channels.tsv, _events.tsv)
    sub-<participant>/motion/sub-<p>_task-armelevation_tracksys-imu_run-<trial>_motion.tsv (.json, …)
    sub-<participant>/beh/sub-<p>_task-armelevation_run-<trial>_recording-loop_physio.tsv.gz (.json)

One task (the paper's arm elevation), one run per trial numbered by its trial id in the store (so a
file names its trial), the condition and speed in the events. The store's participant ids are the
subject labels with every character that is not a letter or digit dropped (``P-01`` → ``P01``; two
ids that would meet are refused).
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, Final

import pandas as pd

from bowden.errors import StoreError

BIDS_VERSION: Final = "1.11.0"
TASK: Final = "armelevation"
TRACKING_SYSTEM: Final = "imu"
LOOP_RECORDING: Final = "loop"


def subject_labels(participants: Iterable[str]) -> dict[str, str]:
    """Each participant id → its BIDS label (letters and digits only).

    Raises
    ------
    StoreError
        Two ids give one label, or an id gives none (names them).
    """
    labels: dict[str, str] = {}
    for participant in participants:
        label = re.sub(r"[^A-Za-z0-9]", "", participant)
        if not label:
            raise StoreError(f"participant {participant!r} has no letter or digit for a BIDS subject label")
        clash = [p for p, other in labels.items() if other == label]
        if clash:
            raise StoreError(
                f"participants {clash[0]!r} and {participant!r} would both be BIDS subject sub-{label}"
            )
        labels[participant] = label
    return labels


def run_stem(
    subject: str,
    trial_id: int,
    *,
    session: str | None = None,
    tracksys: str | None = None,
    recording: str | None = None,
) -> str:
    """The entities of one trial's files, in the spec's order (ses, task, tracksys, run, recording)."""
    parts = [f"sub-{subject}", *([f"ses-{session}"] if session is not None else []), f"task-{TASK}"]
    if tracksys is not None:
        parts.append(f"tracksys-{tracksys}")
    parts.append(f"run-{trial_id}")
    if recording is not None:
        parts.append(f"recording-{recording}")
    return "_".join(parts)


def write_json(path: Path, content: Mapping[str, Any]) -> None:
    path.write_text(json.dumps(content, indent=2, allow_nan=False) + "\n")


def write_table(path: Path, frame: pd.DataFrame) -> None:
    """A BIDS TSV: header, tabs, ``n/a`` for missing values, floats as shortest round-trip text."""
    frame.to_csv(path, sep="\t", index=False, na_rep="n/a", lineterminator="\n")


def dataset_description(
    version: str,
    *,
    simulated: bool,
    source: str,
    authors: Sequence[str] = (),
    license_id: str | None = None,
) -> dict[str, Any]:
    """``dataset_description.json``; ``Authors`` and ``License`` (an SPDX identifier, e.g. CC-BY-4.0)
    as ``bowden export --authors/--license`` give them, left out when not given (both RECOMMENDED)."""
    kind = "simulated" if simulated else "recorded"
    described: dict[str, Any] = {
        "Name": f"bowden study ({kind}): arm elevation with a cable-driven shoulder exosuit",
        "BIDSVersion": BIDS_VERSION,
        "DatasetType": "raw",
        "GeneratedBy": [
            {
                "Name": "bowden",
                "Version": version,
                "Description": f"bowden export --bids from the study store {source}",
            }
        ],
    }
    if authors:
        described["Authors"] = list(authors)
    if license_id:
        described["License"] = license_id
    return described


README: Final = """# bowden study

Exported by `bowden export --bids` from a bowden study store.

Each trial is one run of the task `armelevation` (its number is the trial's id in the store):

- `emg/`: the raw sEMG as EDF+ (16-bit codes) or BDF+ (24-bit), one signal per muscle;
  `_channels.tsv` gives each muscle's exact scaling (stored value = `code * code_step` in
  `stored_format`, `volts = value * gain_v + offset_v`); a last data record padded to whole records
  is marked `BAD_ACQ_SKIP` (an EDF+ annotation) and `RecordingDuration` is the stored length;
  values 24 bits cannot hold exactly are kept under `sourcedata/` (`exact_values`);
- `motion/`: the upper-arm elevation measured by the IMU, with each control cycle's time;
- `beh/`: every signal of the control loop (reference and measured elevation, desired tension,
  commanded and measured motor torque, load cell, loop state), with the compensation model the
  controller used in the sidecar (`CompensationModel`);
- `_events.tsv`: the trial (condition, speed, support, stop reason), each repetition of the
  reference, the events the loop logged.

`participants.tsv` holds the participants as registered; `phenotype/` the questionnaires, one
column per item and condition. Where a participant came for several sessions, each run is under its
`ses-<n>` (`sub-*_sessions.tsv`; `ses-unplanned`: trials recorded outside a session plan).
"""


PARTICIPANTS_SIDECAR: Final[dict[str, Any]] = {
    "participant_id": {"Description": "BIDS label of the store's pseudonymous participant id."},
    "bowden_id": {"Description": "The participant's id in the bowden store."},
    "sex": {
        "Description": "Sex as registered.",
        "Levels": {"male": "male", "female": "female", "other": "other"},
    },
    "height": {"Description": "Body height.", "Units": "m"},
    "weight": {"Description": "Body mass.", "Units": "kg"},
    "age": {"Description": "Age at registration.", "Units": "year"},
    "arm_side": {"Description": "The arm the suit assisted."},
    "hand_load": {"Description": "Load held in the hand.", "Units": "kg"},
}


def participants_table(registry: pd.DataFrame, labels: Mapping[str, str]) -> pd.DataFrame:
    """``participants.tsv`` from the store's participants (every participant with a trial listed)."""
    rows = registry.set_index("id") if not registry.empty else pd.DataFrame()
    table = pd.DataFrame(
        {"participant_id": [f"sub-{label}" for label in labels.values()], "bowden_id": list(labels)}
    )
    for column, source in (
        ("sex", "sex"),
        ("height", "height_m"),
        ("weight", "mass_kg"),
        ("age", "age_years"),
        ("arm_side", "arm_side"),
        ("hand_load", "hand_load_kg"),
    ):
        values = rows[source] if source in rows else pd.Series(dtype=object)
        table[column] = [values.get(participant) for participant in labels]
    return table


def phenotype_tables(
    answers: pd.DataFrame, labels: Mapping[str, str]
) -> dict[str, tuple[pd.DataFrame, dict[str, Any]]]:
    """One table per questionnaire: a row per participant, a column ``<item>_<condition>`` per score."""
    tables: dict[str, tuple[pd.DataFrame, dict[str, Any]]] = {}
    if answers.empty:
        return tables
    for questionnaire, group in answers.groupby("questionnaire", sort=True):
        wide = group.assign(column=group["item"] + "_" + group["condition"]).pivot_table(
            index="participant", columns="column", values="score", aggfunc="first"
        )
        wide = wide.reindex(index=[p for p in labels if p in wide.index])
        table = pd.DataFrame({"participant_id": [f"sub-{labels[p]}" for p in wide.index]})
        sidecar: dict[str, Any] = {"participant_id": {"Description": "BIDS subject label."}}
        for column in wide.columns:
            item, condition = _split(group, column)
            table[column] = [None if pd.isna(v) else int(v) for v in wide[column]]
            sidecar[column] = {
                "Description": f"{questionnaire}: score of {item!r} after the {condition} trials."
            }
        tables[_safe_name(str(questionnaire))] = (table, sidecar)
    return tables


def _split(group: pd.DataFrame, column: str) -> tuple[str, str]:
    for item, condition in group[["item", "condition"]].drop_duplicates().itertuples(index=False, name=None):
        if f"{item}_{condition}" == column:
            return str(item), str(condition)
    return column, "?"


def _safe_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]", "", name) or "questionnaire"


def acq_time(iso_utc: str) -> str:
    """A stored UTC time as BIDS ``acq_time`` (``YYYY-MM-DDThh:mm:ss[.ffffff]Z``)."""
    stamp = pd.Timestamp(iso_utc)
    stamp = stamp.tz_localize("UTC") if stamp.tzinfo is None else stamp.tz_convert("UTC")
    return stamp.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def check_empty_target(directory: Path) -> None:
    """Refuse a directory that holds anything but a previous export of bowden (a BIDS dataset it made)."""
    if not directory.exists() or not any(directory.iterdir()):
        return
    description = directory / "dataset_description.json"
    try:
        made_by = json.loads(description.read_text())["GeneratedBy"][0]["Name"]
    except (OSError, ValueError, KeyError, IndexError, TypeError):
        made_by = None
    if made_by != "bowden":
        raise StoreError(
            f"--bids {directory} is not empty and holds no bowden export: choose a new or empty directory"
        )
