"""A trial's control samples in the store: chunks of encoded columns, or the rows of an old store.

Schema 4 stores samples in ``sample_chunks`` (:mod:`bowden.store.schema`): each row a block
of consecutive control cycles, its columns encoded losslessly by :mod:`bowden.store.column_codec`
(sensor readings on a known grid as their integer codes, float32 readings as float32).
Stores of schema 3 and older hold one row per cycle in ``samples``; every reader here reads both, so
an old store opens as it is and a new trial in it goes to the chunks.
"""

from __future__ import annotations

import logging
import math
import sqlite3
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import pandas as pd

from bowden.contracts import TRIAL_COLUMNS, TRIAL_FAULT, TRIAL_STATE, TRIAL_TIME
from bowden.errors import StoreError
from bowden.store.column_codec import decode_columns, encode_columns, round_trip_problem
from bowden.store.sensor_grids import KNOWN_GRIDS

_log = logging.getLogger(__name__)

# Rows of a full chunk: about 33 s at 500 Hz, 1.6 MB decoded. Bigger chunks compress a little
# better (2 % from 8192 to 32768 rows); this size keeps a reader's memory small.
CHUNK_ROWS: Final = 16384

# The state and fault codes are whole numbers (int64); the other columns float64.
INTEGER_COLUMNS: Final = frozenset({TRIAL_STATE, TRIAL_FAULT})
# Columns that may not be missing (NaN), as the old table's NOT NULL said.
_REQUIRED: Final = (TRIAL_TIME, TRIAL_STATE, TRIAL_FAULT)

INSERT_CHUNK_SQL: Final = (
    "INSERT INTO sample_chunks (trial_id, start_time_s, end_time_s, row_count, data) VALUES (?, ?, ?, ?, ?)"
)
_LEGACY_TABLE: Final = "samples"

Columns = dict[str, np.ndarray[Any, Any]]
ColumnsView = Mapping[str, np.ndarray[Any, Any]]
# A chunk's row without its trial: start and end time, rows, BLOB.
EncodedChunk = tuple[float, float, int, bytes]


def has_table(connection: sqlite3.Connection, name: str) -> bool:
    row = connection.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?", (name,))
    return row.fetchone() is not None


@dataclass(frozen=True)
class ScreenedRows:
    """Recorder rows split into what can be stored and what cannot (:func:`screen_rows`)."""

    columns: Columns | None  # the storable rows' columns (None: none was)
    rejected: int  # rows that cannot be stored
    first_problem: str  # why the first of them cannot ("" if none)
    first_time_s: float  # its time (NaN if that is the problem)


def screen_rows(rows: Sequence[Sequence[float | int]]) -> ScreenedRows:
    """The recorder's rows (``TRIAL_COLUMNS`` order, each of that length) with the unstorable ones
    set aside: a value that is not a number, a time that is not finite, a state or fault code that is
    not a whole number. One such row is dropped, never the rows around it (the writer counts it).
    """
    try:
        array = np.array(rows, dtype=np.float64).reshape(len(rows), len(TRIAL_COLUMNS))
        numeric = np.ones(len(rows), dtype=bool)
    except (TypeError, ValueError):  # a value that is not a number: find its rows one by one
        array, numeric = _numeric_rows(rows)
    time = array[:, 0]
    good = numeric & np.isfinite(time)
    for name in INTEGER_COLUMNS:
        codes = array[:, TRIAL_COLUMNS.index(name)]
        with np.errstate(invalid="ignore"):
            good &= np.isfinite(codes) & (codes == np.round(codes)) & (np.abs(codes) < 2.0**63)
    if good.all():
        return ScreenedRows(_typed(_split(array)), 0, "", math.nan)
    first = int(np.flatnonzero(~good)[0])
    kept = array[good]
    return ScreenedRows(
        _typed(_split(kept)) if kept.size else None,
        int((~good).sum()),
        _row_problem(rows[first], array[first], bool(numeric[first])),
        float(time[first]),
    )


def _numeric_rows(rows: Sequence[Sequence[float | int]]) -> tuple[np.ndarray[Any, Any], np.ndarray[Any, Any]]:
    array = np.full((len(rows), len(TRIAL_COLUMNS)), np.nan)
    numeric = np.zeros(len(rows), dtype=bool)
    for i, row in enumerate(rows):
        try:
            array[i] = np.asarray(row, dtype=np.float64)
        except (TypeError, ValueError):
            continue
        numeric[i] = True
    return array, numeric


def _row_problem(row: Sequence[object], values: np.ndarray[Any, Any], numeric: bool) -> str:
    if not numeric:
        return f"a value is not a number ({row!r})"
    if not math.isfinite(values[0]):
        return f"{TRIAL_TIME} is {float(values[0])!r}, not a finite time"
    for name in INTEGER_COLUMNS:
        value = float(values[TRIAL_COLUMNS.index(name)])
        if not (math.isfinite(value) and value == round(value)):
            return f"{name} is {value!r}, not a whole-number code"
    return f"{TRIAL_STATE}/{TRIAL_FAULT} out of range"


def _split(array: np.ndarray[Any, Any]) -> Columns:
    return {name: array[:, i] for i, name in enumerate(TRIAL_COLUMNS)}


def columns_from_frame(frame: pd.DataFrame) -> Columns:
    """The ``TRIAL_COLUMNS`` of a trial's DataFrame as stored (float64; state and fault int64).

    Raises
    ------
    StoreError
        A column is missing or not numeric, or time, state or fault is missing in a row.
    """
    missing = [name for name in TRIAL_COLUMNS if name not in frame.columns]
    if missing:
        raise StoreError(f"trial samples lack the column(s) {missing}")
    columns: Columns = {}
    for name in TRIAL_COLUMNS:
        try:
            columns[name] = frame[name].to_numpy(dtype=np.float64, na_value=np.nan)
        except (TypeError, ValueError):
            raise StoreError(f"trial samples: column {name!r} is not numeric") from None
    return _typed(columns)


def _typed(columns: Columns) -> Columns:
    for name in _REQUIRED:
        if np.isnan(columns[name]).any():
            row = int(np.flatnonzero(np.isnan(columns[name]))[0])
            raise StoreError(f"trial samples: {name} is missing (NaN) in row {row}; it must always be set")
    for name in INTEGER_COLUMNS:
        values = columns[name]
        if not np.array_equal(values, np.round(values)):
            raise StoreError(f"trial samples: {name} must hold whole numbers (codes)")
        columns[name] = values.astype(np.int64)
    for name in TRIAL_COLUMNS:
        if name not in INTEGER_COLUMNS:
            columns[name] = np.ascontiguousarray(columns[name], dtype=np.float64)
    return columns


def encode_chunk(columns: ColumnsView, *, compress: bool = True) -> EncodedChunk:
    """A block of columns (at least one row) as a chunk without its trial; ``compress`` as in
    :func:`bowden.store.column_codec.encode_columns`. The motor's and the load cell's readings are
    kept as codes where they lie on a known sensor grid (:data:`~bowden.store.sensor_grids.KNOWN_GRIDS`)."""
    time = columns[TRIAL_TIME]
    blob = encode_columns(columns, compress=compress, grids=KNOWN_GRIDS)
    return float(time[0]), float(time[-1]), int(time.size), blob


def verified_chunk(columns: ColumnsView, *, compress: bool = True) -> EncodedChunk:
    """:func:`encode_chunk`, decoded again and compared bit for bit with ``columns``: for a chunk that
    will be the rows' only copy (a merge deletes the small chunks; a trial's frames are dropped).

    Raises
    ------
    StoreError
        The chunk does not give the rows back (names the column and the first row that differs).
    """
    chunk = encode_chunk(columns, compress=compress)
    problem = round_trip_problem(chunk[3], columns)
    if problem is not None:
        raise StoreError(f"an encoded chunk of samples does not decode to its rows: {problem}")
    return chunk


def faithful_chunk(columns: ColumnsView) -> tuple[EncodedChunk, str | None]:
    """A chunk that decodes to ``columns``: compressed, or else raw (the cheapest filters, no zstd),
    with why the compressed one was not faithful (None when it was).

    Raises
    ------
    StoreError
        Neither decodes to the rows: nothing can store them faithfully.
    """
    try:
        return verified_chunk(columns), None
    except StoreError as error:
        return verified_chunk(columns, compress=False), str(error)


def chunk_row(
    trial_id: int, columns: ColumnsView, *, compress: bool = True
) -> tuple[int, float, float, int, bytes]:
    """The ``sample_chunks`` row of a block of columns (see :func:`encode_chunk`)."""
    return (trial_id, *encode_chunk(columns, compress=compress))


def split_columns(columns: ColumnsView, size: int = CHUNK_ROWS) -> Iterator[Columns]:
    """Consecutive blocks of at most ``size`` rows."""
    rows = len(columns[TRIAL_TIME])
    for start in range(0, rows, size):
        yield {name: values[start : start + size] for name, values in columns.items()}


def concat_columns(blocks: Sequence[ColumnsView]) -> Columns:
    return {name: np.concatenate([block[name] for block in blocks]) for name in TRIAL_COLUMNS}


def encode_samples(columns: ColumnsView) -> list[EncodedChunk]:
    """A trial's samples as full chunks, each decoded and compared before the caller lets the
    samples go (:func:`faithful_chunk`; anywhere: a worker can do it for the writer).

    Raises
    ------
    StoreError
        A chunk cannot be encoded so that it decodes to its rows (nothing is stored).
    """
    chunks = []
    for block in split_columns(columns):
        chunk, problem = faithful_chunk(block)
        if problem is not None:
            _log.error("%s; these %d rows are stored uncompressed instead", problem, chunk[2])
        chunks.append(chunk)
    return chunks


def insert_encoded_samples(
    connection: sqlite3.Connection, trial_id: int, chunks: Sequence[EncodedChunk]
) -> None:
    """Insert chunks of :func:`encode_samples` as the trial's (inside the caller's transaction)."""
    connection.executemany(INSERT_CHUNK_SQL, ((trial_id, *chunk) for chunk in chunks))


ChunkRow = tuple[int, float, float, int, bytes]  # a sample_chunks row: trial_id, then an EncodedChunk


def insert_chunk(connection: sqlite3.Connection, row: ChunkRow) -> int:
    """Insert one :func:`chunk_row` (inside the caller's transaction); return its rowid."""
    cursor = connection.execute(INSERT_CHUNK_SQL, row)
    return int(cursor.lastrowid or 0)


def insert_chunks(connection: sqlite3.Connection, rows: Iterable[ChunkRow]) -> None:
    """Insert :func:`chunk_row` rows (inside the caller's transaction)."""
    connection.executemany(INSERT_CHUNK_SQL, rows)


def delete_chunks(connection: sqlite3.Connection, rowids: Iterable[int]) -> None:
    """Delete chunks by rowid (the recorder's small chunks, once merged)."""
    connection.executemany("DELETE FROM sample_chunks WHERE rowid = ?", ((rowid,) for rowid in rowids))


def iter_trial_samples(connection: sqlite3.Connection, trial_id: int) -> Iterator[pd.DataFrame]:
    """A trial's samples a chunk at a time (at most :data:`CHUNK_ROWS` rows each), in time order of
    the chunks; bounded memory whatever the trial's length. Old stores' rows come in blocks too.

    Raises
    ------
    StoreError
        A chunk cannot be decoded or lacks a column (names the trial).
    """
    if has_table(connection, _LEGACY_TABLE):
        cursor = connection.execute(
            f"SELECT {', '.join(TRIAL_COLUMNS)} FROM samples WHERE trial_id = ? ORDER BY {TRIAL_TIME}",
            (trial_id,),
        )
        while rows := cursor.fetchmany(CHUNK_ROWS):
            yield _legacy_frame(rows)
    cursor = connection.execute(
        "SELECT data FROM sample_chunks WHERE trial_id = ? ORDER BY start_time_s, rowid", (trial_id,)
    )
    for (blob,) in cursor:
        try:
            columns = decode_columns(blob)
            frame = pd.DataFrame({name: columns[name] for name in TRIAL_COLUMNS})
        except (StoreError, KeyError) as error:
            raise StoreError(f"trial {trial_id}: a stored chunk of samples is unreadable ({error})") from None
        yield frame


def read_trial_samples(connection: sqlite3.Connection, trial_id: int) -> pd.DataFrame:
    """A trial's samples, ordered by time (an empty frame with the columns if it has none)."""
    frames = list(iter_trial_samples(connection, trial_id))
    if not frames:
        return _legacy_frame([])
    frame = frames[0] if len(frames) == 1 else pd.concat(frames, ignore_index=True)
    if not frame[TRIAL_TIME].is_monotonic_increasing:  # as the old ORDER BY time_s did
        frame = frame.sort_values(TRIAL_TIME, kind="stable", ignore_index=True)
    return frame


def delete_trial_samples(connection: sqlite3.Connection, trial_id: int) -> None:
    connection.execute("DELETE FROM sample_chunks WHERE trial_id = ?", (trial_id,))
    if has_table(connection, _LEGACY_TABLE):
        connection.execute("DELETE FROM samples WHERE trial_id = ?", (trial_id,))


def trials_with_samples(connection: sqlite3.Connection) -> list[int]:
    """Ids of the trials that have samples, in order."""
    query = "SELECT DISTINCT trial_id FROM sample_chunks"
    if has_table(connection, _LEGACY_TABLE):
        query += " UNION SELECT DISTINCT trial_id FROM samples"
    return sorted(int(row[0]) for row in connection.execute(query))


def last_sample_times(connection: sqlite3.Connection) -> dict[int, float]:
    """Per trial, the loop time of its last recorded cycle."""
    query = "SELECT trial_id, MAX(end_time_s) FROM sample_chunks GROUP BY trial_id"
    if has_table(connection, _LEGACY_TABLE):
        query += f" UNION ALL SELECT trial_id, MAX({TRIAL_TIME}) FROM samples GROUP BY trial_id"
    last: dict[int, float] = {}
    for trial_id, time in connection.execute(query):
        if time is not None:
            last[int(trial_id)] = max(float(time), last.get(int(trial_id), -np.inf))
    return last


def sample_count(connection: sqlite3.Connection, trial_id: int | None = None) -> int:
    """Rows stored for a trial (or for every trial)."""
    where, params = ("WHERE trial_id = ?", (trial_id,)) if trial_id is not None else ("", ())
    total = int(connection.execute(f"SELECT COALESCE(SUM(row_count), 0) FROM sample_chunks {where}", params)
                .fetchone()[0])
    if has_table(connection, _LEGACY_TABLE):
        total += int(connection.execute(f"SELECT COUNT(*) FROM samples {where}", params).fetchone()[0])
    return total


def _legacy_frame(rows: Sequence[tuple[Any, ...]]) -> pd.DataFrame:
    """Rows of the old table as a frame: NULL back to NaN, the codes int64."""
    array = np.array(rows, dtype=np.float64).reshape(len(rows), len(TRIAL_COLUMNS))  # None -> NaN
    return pd.DataFrame(
        {
            name: array[:, i].astype(np.int64) if name in INTEGER_COLUMNS else array[:, i]
            for i, name in enumerate(TRIAL_COLUMNS)
        }
    )


def read_samples(connection: sqlite3.Connection, trial_id: int | None = None) -> pd.DataFrame:
    """The samples of one trial, or of every trial, as ``trial_id`` + ``TRIAL_COLUMNS`` ordered by
    trial then time: what ``SELECT * FROM samples`` gave before schema 4 (NaN where it gave NULL)."""
    ids = [trial_id] if trial_id is not None else trials_with_samples(connection)
    frames = [read_trial_samples(connection, i).assign(trial_id=i) for i in ids]
    frame = pd.concat(frames, ignore_index=True) if frames else _legacy_frame([]).assign(trial_id=0).iloc[:0]
    return frame.loc[:, ["trial_id", *TRIAL_COLUMNS]]
