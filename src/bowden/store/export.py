"""Export of a study store to Parquet (the default) or CSV files, one per table, for R, SPSS and
MATLAB users.

The export streams: the samples and the raw sEMG go out a stored chunk at a time
(:meth:`~bowden.store.study_store.StudyStore.trial_sample_chunks`), gathered into row groups of at most
:data:`BATCH_ROWS` rows, so its memory stays bounded whatever the store's size (benchmarks/export.py
measures it); the other tables are small.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from functools import partial
from pathlib import Path
from typing import IO, Any, Final, Protocol

import pandas as pd
import pyarrow as pa
import pyarrow.csv as pcsv
import pyarrow.parquet as pq

from bowden.contracts import TRIAL_COLUMNS, TRIAL_FAULT, TRIAL_STATE, TRIAL_TIME
from bowden.errors import OutputFileError, StoreError


class ExportSource(Protocol):
    """What an export reads from a store (:class:`bowden.store.study_store.StudyStore` is one).

    A protocol rather than the store class, so this module does not import the store that calls it.
    """

    def read_sql(self, query: str, params: tuple[Any, ...] = ()) -> pd.DataFrame: ...

    def trial_sample_chunks(self, trial_id: int) -> Iterator[pd.DataFrame]: ...

    def trials_with_samples(self) -> list[int]: ...

    def trial_emg_chunks(self, trial_id: int) -> Iterator[pd.DataFrame]: ...

    def trials_with_emg(self) -> list[int]: ...

    def emg_muscles(self) -> list[str]: ...


EXPORT_FORMATS: Final = ("parquet", "csv")
# Rows gathered before a write: a Parquet row group, a CSV block (about 20 MB of samples).
BATCH_ROWS: Final = 131072

# The tables every export holds, in order, and the query of each (the samples are streamed from
# their chunks: no query). Samples and events carry their trial's labels so that each file can be
# read on its own.
SAMPLES_TABLE: Final = "samples"
_TABLE_QUERIES: Final = {
    "participants": "SELECT id, sex, height_m, mass_kg, metadata FROM participants ORDER BY id",
    "trials": "SELECT * FROM trials ORDER BY id",
    SAMPLES_TABLE: "",
    "events": "SELECT t.participant, t.condition, t.speed, e.* FROM events e JOIN trials t "
    "ON t.id = e.trial_id ORDER BY e.trial_id, e.time_s",
    "questionnaires": "SELECT participant, condition, questionnaire, item, score, submitted_utc "
    "FROM questionnaires ORDER BY participant, condition, questionnaire, item",
    "outcomes": "SELECT participant, condition, speed, trial_id, repetition, phase, measure, value "
    "FROM outcomes",
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
        for (name, query), path in zip(_TABLE_QUERIES.items(), paths, strict=False):
            if name == SAMPLES_TABLE:
                write = partial(_write_samples, store, file_format=file_format)
            else:
                write = partial(_write_frame, store.read_sql(query), file_format=file_format)
            _write_atomically(path, write)
        if include_emg:
            _write_atomically(paths[-1], partial(_write_emg, store, file_format=file_format))
    except OSError as error:
        raise OutputFileError(f"cannot export the store to {out}: {error.strerror or error}") from None
    return paths


_LABELS: Final = ("participant", "condition", "speed")
_INTEGER_COLUMNS: Final = (TRIAL_STATE, TRIAL_FAULT)


def _labelled(
    store: ExportSource, trial_ids: Iterable[int], chunks: Callable[[int], Iterator[pd.DataFrame]]
) -> Iterator[tuple[dict[str, Any], pd.DataFrame]]:
    """Each chunk of each trial with the trial's id, participant, condition and speed."""
    trials = store.read_sql("SELECT id, participant, condition, speed FROM trials ORDER BY id")
    labels = {
        int(trial_id): {"trial_id": int(trial_id), "participant": p, "condition": c, "speed": s}
        for trial_id, p, c, s in trials.itertuples(index=False, name=None)
    }
    for trial_id in trial_ids:
        for chunk in chunks(trial_id):
            yield labels[trial_id], chunk


def _write_samples(store: ExportSource, path: Path, *, file_format: str) -> None:
    """Every trial's samples: participant, condition, speed, trial_id, then the trial columns."""
    schema = pa.schema(
        [(name, pa.string()) for name in _LABELS]
        + [("trial_id", pa.int64())]
        + [(name, pa.int64() if name in _INTEGER_COLUMNS else pa.float64()) for name in TRIAL_COLUMNS]
    )
    with _TableWriter(path, schema, file_format) as writer:
        for labels, chunk in _labelled(store, store.trials_with_samples(), store.trial_sample_chunks):
            writer.write({**labels, **{name: chunk[name].to_numpy() for name in TRIAL_COLUMNS}}, len(chunk))


def _write_emg(store: ExportSource, path: Path, *, file_format: str) -> None:
    """Every trial's stored EMG as rows of ``path``: labels, time_s, the union of the muscles."""
    muscles = store.emg_muscles()
    schema = pa.schema(
        [("trial_id", pa.int64())]
        + [(name, pa.string()) for name in _LABELS]
        + [(name, pa.float64()) for name in (TRIAL_TIME, *muscles)]
    )
    with _TableWriter(path, schema, file_format) as writer:
        for labels, chunk in _labelled(store, store.trials_with_emg(), store.trial_emg_chunks):
            # A muscle this trial did not record is missing (null) in its rows.
            columns = {name: chunk[name].to_numpy() for name in (TRIAL_TIME, *muscles) if name in chunk}
            writer.write({**labels, **columns}, len(chunk))


class _TableWriter:
    """Rows appended in blocks to a Parquet file (row groups) or a CSV file (header once)."""

    def __init__(self, path: Path, schema: pa.Schema, file_format: str) -> None:
        self._schema = schema
        self._pending: list[pa.RecordBatch] = []
        self._rows = 0
        self._parquet = pq.ParquetWriter(path, schema) if file_format == "parquet" else None
        self._csv: IO[bytes] | None = None
        self._csv_writer: pcsv.CSVWriter | None = None
        if self._parquet is None:
            self._csv = path.open("wb")
            self._csv.write((",".join(schema.names) + "\n").encode())
            options = pcsv.WriteOptions(include_header=False)
            self._csv_writer = pcsv.CSVWriter(self._csv, schema, write_options=options)

    def write(self, columns: dict[str, Any], rows: int) -> None:
        """Append ``rows`` rows; a scalar column repeats, None is a missing (null) column."""
        arrays = []
        for field in self._schema:
            value = columns.get(field.name)
            if value is None or not hasattr(value, "__len__") or isinstance(value, str):
                arrays.append(pa.repeat(pa.scalar(value, type=field.type), rows))
            else:  # NaN is written as missing, as pandas exports did
                arrays.append(pa.array(value, type=field.type, from_pandas=True))
        self._pending.append(pa.RecordBatch.from_arrays(arrays, schema=self._schema))
        self._rows += rows
        if self._rows >= BATCH_ROWS:
            self._flush()

    def _flush(self) -> None:
        if self._pending:
            table = pa.Table.from_batches(self._pending, schema=self._schema)
            if self._parquet is not None:
                self._parquet.write_table(table)
            elif self._csv_writer is not None:
                self._csv_writer.write_table(table)
        self._pending, self._rows = [], 0

    def __enter__(self) -> _TableWriter:
        return self

    def __exit__(self, exc_type: object, exc: object, tb: object) -> None:
        try:
            if exc_type is None:
                self._flush()
        finally:
            if self._parquet is not None:
                self._parquet.close()
            if self._csv_writer is not None:
                self._csv_writer.close()
            if self._csv is not None:
                self._csv.close()


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
