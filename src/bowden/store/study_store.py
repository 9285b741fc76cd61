"""The study store: one SQLite file per study.

It extends the runtime's trial store (:mod:`bowden.store.schema`: ``trials``, ``samples``,
``events``) — so a trial recorded live on the suit and a simulated one land in the same tables — with

``participants``
    the registry (:mod:`bowden.web.registry`): pseudonymous id, sex, height, mass, arm side, hand
    load, age (never a name);
``emg_chunks``
    the raw sEMG: per trial and muscle, blocks of 16-bit codes (the resolution of EDF/BDF-16 files)
    with the gain, rate and start time on the controller time base, compressed losslessly
    (:mod:`bowden.store.emg_chunks`; stores of schema 3 and older keep one raw ``emg`` row per trial
    and muscle, still read);
``questionnaires``
    one row per answered item: participant, condition, questionnaire, item, score (the table of
    :mod:`bowden.web.questionnaire_store`, which the browser forms write);
``outcomes``
    the tidy outcome table of the analysis;
``artifacts``
    named text documents of the study (the identified ``model.json``, the identification summary,
    the settings the study ran with);
``sessions``, ``plan_steps``, ``session_trials``, ``session_notes``
    the session plans of :mod:`bowden.store.sessions` (``bowden serve``).

Why SQLite over DuckDB: the recorder must commit every 0.1 s from a small ARM board and survive
``kill -9``; SQLite's WAL gives that from the standard library. Analyses read whole trials into
pandas, where DuckDB's column engine would buy little; the signals are stored as compressed column
chunks (:mod:`bowden.store.column_codec`), so SQLite holds a few rows per trial, not one per sample.
"""

from __future__ import annotations

import json
import math
import sqlite3
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, Final, Self

import numpy as np
import pandas as pd

from bowden.contracts import (
    is_participant_id,
)
from bowden.errors import StoreError
from bowden.model import Subject
from bowden.store import emg_chunks, sample_chunks
from bowden.store.export import export_store
from bowden.store.ownership import made_by_study_pipeline, metadata_object
from bowden.store.participants import upsert_anthropometrics
from bowden.store.questionnaires import checked_answer, upsert_answers
from bowden.store.schema import configure_connection, create_schema
from bowden.store.tables import create_study_tables
from bowden.store.trial_encoding import EncodedTrial, encode_trial
from bowden.store.trials import (
    TrialInfo,
    condition_supports,
    delete_trial_row,
    end_trial,
    insert_trial,
    replace_event,
    speed_peaks,
    utc_now_iso,
)

# The outcome table's columns as read and exported: the analysis's, with each row's trial after its
# speed (stored last in the table: stores before schema 6 gained the column at the end).
OUTCOME_TABLE_COLUMNS: Final = (
    "participant", "condition", "speed", "trial_id", "repetition", "phase", "measure", "value",
)


def check_participant_id(participant: str) -> str:
    """Accept pseudonymous ids such as ``P07`` or ``S112``; refuse anything that could be a name.

    The one rule of :func:`bowden.contracts.is_participant_id` (the whole text: 1–4 capital letters,
    then 1–4 digits), checked on every write. Reads do not check, so stores written under an older,
    looser rule stay readable.
    """
    if not is_participant_id(participant):
        raise StoreError(
            f"participant id {participant!r} is not pseudonymous: use 1–4 capital letters then 1–4 "
            "digits (e.g. P07); never store names"
        )
    return participant


@dataclass(frozen=True, kw_only=True)
class StoredTrial:
    """A completed trial of the store."""

    trial_id: int
    participant: str
    condition: str
    speed: str
    support: float | None


class StudyStore:
    """Open (or create) a study store file; use as a context manager.

    ``synchronous="FULL"`` fsyncs every commit (live recording on a battery-powered suit);
    ``"NORMAL"`` is enough for simulated studies (crash-safe, not power-cut-safe) and much faster.
    """

    def __init__(self, path: str | Path, *, synchronous: str = "NORMAL") -> None:
        self.path = Path(path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._db = sqlite3.connect(self.path)
            configure_connection(self._db, synchronous=synchronous)
            create_schema(self._db)
            with self._db:
                create_study_tables(self._db)  # older stores migrated (bowden.store.tables)
        except sqlite3.Error as error:
            raise StoreError(f"cannot open the study store {self.path}: {error}") from None
        except OSError as error:  # its folder cannot be made (under a file, /proc, no permission)
            raise StoreError(f"cannot open the study store {self.path}: {error.strerror or error}") from None

    def close(self) -> None:
        self._db.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    # --- participants ----------------------------------------------------------------------------
    def add_participant(
        self, participant: str, subject: Subject, metadata: Mapping[str, Any] | None = None
    ) -> None:
        """Insert or update a participant's anthropometrics."""
        check_participant_id(participant)
        with self._db:
            upsert_anthropometrics(
                self._db, participant, sex=subject.sex, height_m=subject.height_m, mass_kg=subject.mass_kg,
                metadata_json=json.dumps(dict(metadata or {}), allow_nan=False),
            )

    def participants(self) -> pd.DataFrame:
        """Participants: id, sex, height_m, mass_kg."""
        return pd.read_sql_query("SELECT id, sex, height_m, mass_kg FROM participants ORDER BY id", self._db)

    def subject(self, participant: str) -> Subject:
        row = self._db.execute(
            "SELECT sex, height_m, mass_kg FROM participants WHERE id = ?", (participant,)
        ).fetchone()
        if row is None:
            raise StoreError(f"participant {participant!r} is not in {self.path}")
        return Subject(sex=row[0], height_m=row[1], mass_kg=row[2])

    # --- trials ----------------------------------------------------------------------------------
    def write_trial(
        self,
        info: TrialInfo,
        samples: pd.DataFrame,
        *,
        emg: pd.DataFrame | None = None,
        stop_reason: str = "completed",
    ) -> int:
        """Store a whole trial (samples and optional EMG) in one transaction; return its id.

        ``samples`` has the ``contracts.TRIAL_COLUMNS``; ``emg`` has ``time_s`` (controller time base)
        and one column per muscle at a constant rate. Either all of it is committed or none.
        """
        return self.write_encoded_trial(info, encode_trial(samples, emg), stop_reason=stop_reason)

    def write_encoded_trial(
        self, info: TrialInfo, trial: EncodedTrial, *, stop_reason: str = "completed"
    ) -> int:
        """Store a trial encoded by :func:`~bowden.store.trial_encoding.encode_trial` (in a worker,
        perhaps) in one transaction; return its id."""
        check_participant_id(info.participant)
        try:
            with self._db:
                trial_id = insert_trial(self._db, info)
                sample_chunks.insert_encoded_samples(self._db, trial_id, trial.samples)
                emg_chunks.insert_encoded_emg(self._db, trial_id, trial.emg)
                end_trial(self._db, trial_id, stop_reason)
        except sqlite3.Error as error:
            raise StoreError(f"cannot write the trial into {self.path}: {error}") from None
        return trial_id

    def replace_emg(
        self,
        emg: Mapping[int, Sequence[emg_chunks.EncodedEmgChunk]],
        events: Mapping[int, tuple[str, str]],
    ) -> None:
        """Replace the EMG of several trials by chunks already encoded and checked
        (:func:`bowden.store.emg_chunks.encode_verified_emg`), each trial with one event ``(kind,
        message)`` replacing its events of the same kind, in one transaction: every trial is written,
        or none.

        Raises
        ------
        StoreError
            The file cannot be written.
        """
        try:
            with self._db:
                for trial_id, chunks in emg.items():
                    emg_chunks.delete_trial_emg(self._db, trial_id)
                    emg_chunks.insert_encoded_emg(self._db, trial_id, chunks)
                    kind, message = events[trial_id]
                    replace_event(self._db, trial_id, kind, message)
        except sqlite3.Error as error:
            raise StoreError(f"cannot write the EMG into {self.path}: {error}") from None

    def completed_trials(self) -> list[StoredTrial]:
        """Trials that finished (``ended_utc`` set), in recording order."""
        rows = self._db.execute(
            "SELECT id, participant, condition, speed, support FROM trials "
            "WHERE ended_utc IS NOT NULL AND speed IS NOT NULL ORDER BY id"
        ).fetchall()
        return [
            StoredTrial(trial_id=r[0], participant=r[1], condition=r[2], speed=r[3], support=r[4])
            for r in rows
        ]

    def trial_table(self) -> pd.DataFrame:
        """Every trial's row: id, participant, condition, speed, stop_reason, metadata (JSON text)."""
        return pd.read_sql_query(
            "SELECT id, participant, condition, speed, stop_reason, metadata FROM trials ORDER BY id",
            self._db,
        )

    def condition_supports(self) -> list[tuple[str, float]]:
        """Each condition recorded with a support, and that support (:func:`trials.condition_supports`)."""
        return condition_supports(self._db)

    def speed_peaks(self) -> list[tuple[str, float]]:
        """Each speed recorded with its peak in °/s (:func:`trials.speed_peaks`)."""
        return speed_peaks(self._db)

    def events(self, kind: str) -> pd.DataFrame:
        """The events of one kind: trial_id, time_s, message, by trial in recording order."""
        return pd.read_sql_query(
            "SELECT trial_id, time_s, message FROM events WHERE kind = ? ORDER BY trial_id, rowid",
            self._db,
            params=(kind,),
        )

    def trial_events(self, trial_id: int) -> pd.DataFrame:
        """Every event of one trial: time_s, kind, message, in recording order (for exports)."""
        return pd.read_sql_query(
            "SELECT time_s, kind, message FROM events WHERE trial_id = ? ORDER BY rowid",
            self._db,
            params=(trial_id,),
        )

    def trial_sessions(self) -> pd.DataFrame:
        """Each trial started for a session's step: trial_id, session (its id), created_utc (when the
        session was planned), by session then trial (empty in a store without session plans)."""
        return pd.read_sql_query(
            "SELECT t.trial_id, s.id AS session, s.created_utc FROM session_trials t "
            "JOIN sessions s ON s.id = t.session_id ORDER BY s.id, t.trial_id",
            self._db,
        )

    def trial_times_utc(self, trial_id: int) -> tuple[str, str | None]:
        """When a trial started and ended (ISO 8601 UTC as recorded; the end None while open)."""
        query = "SELECT started_utc, ended_utc FROM trials WHERE id = ?"
        row = self._db.execute(query, (trial_id,)).fetchone()
        if row is None:
            raise StoreError(f"{self.path}: no trial {trial_id}")
        return str(row[0]), None if row[1] is None else str(row[1])

    def trial_metadata(self, trial_id: int) -> dict[str, Any]:
        """The JSON metadata recorded with a trial (backend, seed, versions...)."""
        row = self._db.execute("SELECT metadata FROM trials WHERE id = ?", (trial_id,)).fetchone()
        if row is None:
            raise StoreError(f"no trial {trial_id} in {self.path}")
        metadata: dict[str, Any] = json.loads(row[0])
        return metadata

    def discard_unfinished_trials(self) -> int:
        """Delete the study pipeline's trials a crash left open (with their samples, EMG and events).

        Only trials ``bowden study`` recorded (:func:`bowden.store.ownership.made_by_study_pipeline`)
        are deleted: an unfinished trial recorded on the suit keeps every sample committed before the
        crash, and those are data. Returns how many trials were deleted.
        """
        with self._db:
            rows = self._db.execute("SELECT id, metadata FROM trials WHERE ended_utc IS NULL").fetchall()
            ids = [row[0] for row in rows if made_by_study_pipeline(metadata_object(row[1]))]
            for trial_id in ids:
                sample_chunks.delete_trial_samples(self._db, trial_id)
                emg_chunks.delete_trial_emg(self._db, trial_id)
                delete_trial_row(self._db, trial_id)
        return len(ids)

    def trial_samples(self, trial_id: int) -> pd.DataFrame:
        """The samples of a trial (NaN where a value is missing), ordered by time."""
        return sample_chunks.read_trial_samples(self._db, trial_id)

    def trial_sample_chunks(self, trial_id: int) -> Iterator[pd.DataFrame]:
        """The samples of a trial a block at a time (bounded memory, for exports)."""
        return sample_chunks.iter_trial_samples(self._db, trial_id)

    def trials_with_samples(self) -> list[int]:
        """Ids of every trial with samples (finished or not), in order."""
        return sample_chunks.trials_with_samples(self._db)

    def last_sample_times(self) -> dict[int, float]:
        """Per trial id, the loop time of its last recorded cycle."""
        return sample_chunks.last_sample_times(self._db)

    def trial_emg(self, trial_id: int) -> pd.DataFrame | None:
        """The EMG of a trial as ``time_s`` + one column per muscle, or None if none was stored."""
        return emg_chunks.read_trial_emg(self._db, trial_id)

    def trial_emg_chunks(self, trial_id: int) -> Iterator[pd.DataFrame]:
        """The EMG of a trial a block at a time (bounded memory, for exports); nothing if none."""
        return emg_chunks.iter_trial_emg(self._db, trial_id)

    def trial_emg_codes(self, trial_id: int) -> dict[str, emg_chunks.StoredEmgChannel]:
        """The EMG of a trial per muscle as stored codes with their scaling (empty if none stored)."""
        return emg_chunks.read_trial_emg_codes(self._db, trial_id)

    def trials_with_emg(self) -> list[int]:
        """Ids of the trials with stored EMG, in order."""
        return emg_chunks.trials_with_emg(self._db)

    def emg_muscles(self) -> list[str]:
        """Every muscle with stored EMG (the paper's in their order, then others by name)."""
        return emg_chunks.emg_muscles(self._db)

    def iter_trials(
        self, *, with_emg: bool = True
    ) -> Iterator[tuple[StoredTrial, pd.DataFrame, pd.DataFrame | None]]:
        """Every completed trial with its samples (and EMG), one at a time (bounded memory)."""
        for trial in self.completed_trials():
            emg = self.trial_emg(trial.trial_id) if with_emg else None
            yield trial, self.trial_samples(trial.trial_id), emg

    # --- questionnaires --------------------------------------------------------------------------
    def write_questionnaires(self, answers: pd.DataFrame) -> None:
        """Store answers: columns participant, condition, questionnaire, item, score (replaces repeats).

        Every row is checked before anything is written (all rows are stored or none).

        Raises
        ------
        StoreError
            Naming the row and the problem: a missing column, a participant id that is not
            pseudonymous, an unknown condition, questionnaire or item, a score that is missing (NaN),
            not a whole number or outside the questionnaire's range; or the file cannot be written.
        """
        needed = ("participant", "condition", "questionnaire", "item", "score")
        missing = [name for name in needed if name not in answers.columns]
        if missing:
            raise StoreError(f"questionnaire answers lack the column(s) {missing}")
        now = utc_now_iso()
        rows = []
        for label, (participant, condition, questionnaire, item, score) in zip(
            answers.index, answers.loc[:, list(needed)].itertuples(index=False, name=None), strict=True
        ):
            rows.append(
                (*checked_answer(label, participant, condition, questionnaire, item, score), now)
            )
        try:
            with self._db:
                upsert_answers(self._db, rows)
        except sqlite3.Error as error:
            raise StoreError(f"cannot write the questionnaire answers into {self.path}: {error}") from None

    def questionnaires(self) -> pd.DataFrame:
        return pd.read_sql_query(
            "SELECT participant, condition, questionnaire, item, score FROM questionnaires "
            "ORDER BY participant, condition, questionnaire, item",
            self._db,
        )

    # --- outcomes and artifacts ------------------------------------------------------------------
    def replace_outcomes(self, outcomes: pd.DataFrame) -> None:
        """Replace the outcome table by ``outcomes`` (its ``trial_id`` names each row's trial; a frame
        without one stores NULL)."""
        frame = outcomes.reindex(columns=list(OUTCOME_TABLE_COLUMNS))
        with self._db:
            self._db.execute("DELETE FROM outcomes")
            self._db.executemany(
                f"INSERT INTO outcomes ({', '.join(OUTCOME_TABLE_COLUMNS)}) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (
                    (p, c, s, None if pd.isna(t) else int(t), int(r), ph, m,
                     None if not math.isfinite(v) else float(v))
                    for p, c, s, t, r, ph, m, v in frame.itertuples(index=False, name=None)
                ),
            )

    def outcomes(self) -> pd.DataFrame:
        """The outcome table (``trial_id`` missing in rows an older bowden stored)."""
        frame = pd.read_sql_query(f"SELECT {', '.join(OUTCOME_TABLE_COLUMNS)} FROM outcomes", self._db)
        frame["value"] = frame["value"].astype(np.float64)
        frame["trial_id"] = frame["trial_id"].astype("Int64")
        return frame

    def put_artifact(self, name: str, content: str) -> None:
        with self._db:
            self._db.execute(
                "INSERT OR REPLACE INTO artifacts (name, content, updated_utc) VALUES (?, ?, ?)",
                (name, content, utc_now_iso()),
            )

    def artifact(self, name: str) -> str | None:
        row = self._db.execute("SELECT content FROM artifacts WHERE name = ?", (name,)).fetchone()
        return None if row is None else str(row[0])

    # --- export ----------------------------------------------------------------------------------
    def read_sql(self, query: str, params: tuple[Any, ...] = ()) -> pd.DataFrame:
        """The rows of a read-only SQL query as a DataFrame (for exports and ad-hoc analyses)."""
        return pd.read_sql_query(query, self._db, params=params)

    def export(
        self, directory: str | Path, *, file_format: str = "parquet", include_emg: bool = False
    ) -> list[Path]:
        """Write the tables for R, SPSS and MATLAB users (:func:`bowden.store.export.export_store`)."""
        return export_store(self, directory, file_format=file_format, include_emg=include_emg)
