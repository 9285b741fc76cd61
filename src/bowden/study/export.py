"""Export of a study store to Parquet or CSV files, one per table, for R, SPSS and MATLAB users."""

from __future__ import annotations

import os
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any, Final, Protocol

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from bowden.contracts import MUSCLES, TRIAL_TIME
from bowden.errors import OutputFileError, StoreError


class ExportSource(Protocol):
    """What an export reads from a store (:class:`bowden.study.store.StudyStore` is one).

    A protocol rather than the store class, so this module does not import the store that calls it.
    """

    def read_sql(self, query: str, params: tuple[Any, ...] = ()) -> pd.DataFrame: ...

    def trial_emg(self, trial_id: int) -> pd.DataFrame | None: ...

EXPORT_FORMATS: Final = ("parquet", "csv")

# The tables every export holds, in order, and the query of each. Samples and events carry their
# trial's labels so that each file can be read on its own.
_TABLE_QUERIES: Final = {
    "participants": "SELECT id, sex, height_m, mass_kg, metadata FROM participants ORDER BY id",
    "trials": "SELECT * FROM trials ORDER BY id",
    "samples": "SELECT t.participant, t.condition, t.speed, s.* FROM samples s JOIN trials t "
    "ON t.id = s.trial_id ORDER BY s.trial_id, s.time_s",
    "events": "SELECT t.participant, t.condition, t.speed, e.* FROM events e JOIN trials t "
    "ON t.id = e.trial_id ORDER BY e.trial_id, e.time_s",
    "questionnaires": "SELECT participant, condition, questionnaire, item, score, submitted_utc "
    "FROM questionnaires ORDER BY participant, condition, questionnaire, item",
    "outcomes": "SELECT * FROM outcomes",
    "artifacts": "SELECT name, content, updated_utc FROM artifacts ORDER BY name",
}
EMG_TABLE: Final = "emg"


def export_paths(
    directory: str | Path, *, file_format: str = "parquet", include_emg: bool = False
) -> list[Path]:
    """The files :func:`export_store` writes into ``directory``, in order (to check them beforehand)."""
    if file_format not in EXPORT_FORMATS:
        raise StoreError(f"export format must be 'parquet' or 'csv', got {file_format!r}")
    names = [*_TABLE_QUERIES, EMG_TABLE] if include_emg else list(_TABLE_QUERIES)
    return [Path(directory) / f"{name}.{file_format}" for name in names]


def export_store(
    store: ExportSource, directory: str | Path, *, file_format: str = "parquet", include_emg: bool = False
) -> list[Path]:
    """Write the store's tables into ``directory``, one file each; return the files.

    Always written: ``participants``, ``trials``, ``samples`` and ``events`` (each row with its
    trial's participant, condition and speed), ``questionnaires``, ``outcomes``, and ``artifacts``
    (the model and settings documents of the study).

    The raw sEMG is written only with ``include_emg``: at 2 kHz on four muscles it is about twenty
    times the control samples, gigabytes of CSV for a full study. It then goes to ``emg``, one row per
    EMG sample: ``trial_id``, participant, condition, speed, ``time_s`` on the controller's time base
    and one column per muscle (in the stored units), written trial by trial in bounded memory.

    Each file is written under a temporary name and renamed once complete, so an interrupted export
    never leaves a truncated table under a table's name.

    Raises
    ------
    StoreError
        ``file_format`` is not ``"parquet"`` or ``"csv"``.
    OutputFileError
        ``directory`` or a file in it cannot be written (names the directory and the reason).
    """
    out = Path(directory)
    paths = export_paths(out, file_format=file_format, include_emg=include_emg)
    try:
        out.mkdir(parents=True, exist_ok=True)
        for query, path in zip(_TABLE_QUERIES.values(), paths, strict=False):
            _write_atomically(path, partial(_write_frame, store.read_sql(query), file_format=file_format))
        if include_emg:
            _write_atomically(paths[-1], partial(_write_emg, store, file_format=file_format))
    except OSError as error:
        raise OutputFileError(f"cannot export the store to {out}: {error.strerror or error}") from None
    return paths


def _write_emg(store: ExportSource, path: Path, *, file_format: str) -> None:
    """Every trial's stored EMG as rows of ``path``: labels, time_s, the union of the muscles."""
    stored = set(store.read_sql("SELECT DISTINCT muscle FROM emg")["muscle"])
    muscles = [m for m in MUSCLES if m in stored] + sorted(stored - set(MUSCLES))
    trials = store.read_sql(
        "SELECT id, participant, condition, speed FROM trials "
        "WHERE id IN (SELECT trial_id FROM emg) ORDER BY id"
    )
    schema = pa.schema(
        [("trial_id", pa.int64()), ("participant", pa.string())]
        + [("condition", pa.string()), ("speed", pa.string())]
        + [(name, pa.float64()) for name in (TRIAL_TIME, *muscles)]
    )
    if file_format == "csv":
        pd.DataFrame(columns=schema.names).to_csv(path, index=False)
    writer = pq.ParquetWriter(path, schema) if file_format == "parquet" else None
    try:
        for trial_id, participant, condition, speed in trials.itertuples(index=False, name=None):
            emg = store.trial_emg(int(trial_id))
            if emg is None:
                continue
            labels = {"trial_id": int(trial_id), "participant": participant, "condition": condition}
            frame = pd.concat(
                [
                    pd.DataFrame({**labels, "speed": speed}, index=emg.index),
                    emg.reindex(columns=[TRIAL_TIME, *muscles]),
                ],
                axis="columns",
            )
            if writer is not None:
                writer.write_table(pa.Table.from_pandas(frame, schema=schema, preserve_index=False))
            else:
                frame.to_csv(path, index=False, mode="a", header=False)
    finally:
        if writer is not None:
            writer.close()


def _write_frame(frame: pd.DataFrame, path: Path, *, file_format: str) -> None:
    if file_format == "parquet":
        frame.to_parquet(path, index=False)
    else:
        frame.to_csv(path, index=False)


def _write_atomically(path: Path, write: Callable[[Path], None]) -> None:
    """``write`` into a temporary file beside ``path``, renamed over it once complete."""
    tmp = path.with_name(f".{path.name}.partial")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
