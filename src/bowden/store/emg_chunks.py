"""A trial's raw sEMG in the study store: its codes in compressed chunks, or an old store's rows.

Each chunk holds one muscle's samples as codes with a scaling, ``volts = code × gain + offset_v``:

- imported EMG keeps its file's own samples (:class:`~bowden.analysis.emg.read.SourceChannel`): an
  EDF's 16-bit and a BDF's 24-bit digital codes (int16, int32) with the header's scaling, an XDF
  stream's float32 or float64 values, a CSV's numbers, each with its unit's factor: nothing rounded;
- EMG stored from float volts (the simulated study's) is quantised to 16-bit codes with one gain per
  trial and muscle (the trial's peak / 32767), the resolution of EDF files.

Schema 4 and later store them in ``emg_chunks``, one row per muscle and block of
:data:`EMG_CHUNK_SAMPLES` samples, the codes encoded losslessly by :mod:`bowden.store.column_codec`
(16-bit codes: the residual of an exact integer linear prediction; other codes: differences or XOR;
byte planes, zstd). ``offset_v`` came with schema 5; a schema-4 store gains it as 0 when opened.
Where imported EMG replaces a trial's stored EMG, every new chunk is decoded and compared with its
source before the old rows are deleted (:func:`encode_verified_emg`).
Stores of schema 3 and older hold a trial's codes raw in one ``emg`` row per muscle; every reader
here reads both.
"""

from __future__ import annotations

import math
import sqlite3
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import pandas as pd

from bowden.analysis.emg.read import SourceChannel, decode_source
from bowden.contracts import MUSCLES, TRIAL_TIME
from bowden.errors import StoreError
from bowden.store.column_codec import decode_columns, encode_columns
from bowden.store.sample_chunks import has_table

# Samples of a chunk per muscle: about 33 s at 2 kHz, 128 kB of codes. Compresses 0.5 % better than
# 32768 (fewer headers and zstd tables; the predictor needs no shorter blocks) at 0.5 MB of a reader's
# memory per muscle.
EMG_CHUNK_SAMPLES: Final = 65536
_CODES: Final = "codes"
_LEGACY_TABLE: Final = "emg"

# A chunk's row without its trial: muscle, first sample, samples, rate, start time, gain, BLOB, offset.
EncodedEmgChunk = tuple[str, int, int, float, float, float, bytes, float]
_INSERT_SQL = (
    "INSERT INTO emg_chunks (trial_id, muscle, first_sample, sample_count, rate_hz, start_time_s, gain, "
    "data, offset_v) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)"
)
# Codes the column codec has no dtype for, widened without loss.
_WIDER: Final = {"i1": np.int16, "u1": np.int16, "u2": np.int32, "u4": np.int64}


def _storable(codes: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    """The codes in a dtype the column codec stores (8-bit and unsigned codes widened, losslessly)."""
    array = np.ascontiguousarray(codes)
    key = array.dtype.str[1:]
    return array.astype(_WIDER[key]) if key in _WIDER else array


def encode_trial_emg(emg: pd.DataFrame) -> list[EncodedEmgChunk]:
    """A trial's EMG (``time_s`` + one column per muscle, evenly spaced) as encoded chunks (anywhere:
    a worker can do it for the writer).

    Raises
    ------
    StoreError
        No time column, fewer than two samples, uneven spacing, or non-finite samples (names the
        muscle).
    """
    if TRIAL_TIME not in emg.columns or len(emg) < 2:
        raise StoreError("EMG needs a time_s column and at least two samples")
    time = emg[TRIAL_TIME].to_numpy(dtype=np.float64)
    steps = np.diff(time)
    rate = 1.0 / float(np.median(steps))
    if not np.allclose(steps, 1.0 / rate, rtol=1e-3, atol=0.0):
        raise StoreError("EMG samples must be evenly spaced to be stored")
    chunks: list[EncodedEmgChunk] = []
    for muscle in emg.columns:
        if muscle == TRIAL_TIME:
            continue
        values = emg[muscle].to_numpy(dtype=np.float64)
        peak = float(np.max(np.abs(values))) if values.size else 0.0
        if not math.isfinite(peak):
            raise StoreError(f"EMG channel {muscle!r} has non-finite samples")
        gain = peak / 32767.0 if peak > 0.0 else 1.0
        codes = np.rint(values / gain).astype(np.int16)
        for first in range(0, codes.size, EMG_CHUNK_SAMPLES):
            block = codes[first : first + EMG_CHUNK_SAMPLES]
            blob = encode_columns({_CODES: block})
            chunks.append((str(muscle), first, block.size, rate, float(time[0]), gain, blob, 0.0))
    return chunks


def encode_source_emg(
    sources: Mapping[str, SourceChannel], *, start_time_s: float, rate_hz: float
) -> list[EncodedEmgChunk]:
    """A trial's EMG as its file stored it (one :class:`SourceChannel` per muscle, equal lengths):
    the codes as they are, with their scaling.

    Raises
    ------
    StoreError
        Muscles of different lengths, fewer than two samples, or codes the store cannot hold.
    """
    lengths = {muscle: source.codes.size for muscle, source in sources.items()}
    if len(set(lengths.values())) > 1 or min(lengths.values(), default=0) < 2:
        raise StoreError(f"EMG needs at least two samples and as many for every muscle, got {lengths}")
    if not (math.isfinite(rate_hz) and rate_hz > 0.0 and math.isfinite(start_time_s)):
        raise StoreError(f"EMG needs a finite start and a positive rate, got {start_time_s}, {rate_hz}")
    chunks: list[EncodedEmgChunk] = []
    for muscle, source in sources.items():
        codes = _storable(source.codes)
        if codes.dtype.kind == "f" and not np.all(np.isfinite(codes)):
            raise StoreError(f"EMG channel {muscle!r} has non-finite samples")
        for first in range(0, codes.size, EMG_CHUNK_SAMPLES):
            block = codes[first : first + EMG_CHUNK_SAMPLES]
            blob = encode_columns({_CODES: block})
            chunks.append(
                (str(muscle), first, block.size, rate_hz, start_time_s, source.gain_v, blob, source.offset_v)
            )
    return chunks


def encode_verified_emg(
    sources: Mapping[str, SourceChannel], *, start_time_s: float, rate_hz: float
) -> list[EncodedEmgChunk]:
    """:func:`encode_source_emg`, each chunk decoded again and compared with its source bit for bit:
    the chunks that replace a trial's stored EMG (the old rows are deleted only after this).

    Raises
    ------
    StoreError
        A chunk that does not decode to its source's codes (names the muscle and the first sample).
    """
    chunks = encode_source_emg(sources, start_time_s=start_time_s, rate_hz=rate_hz)
    for muscle, first, count, _rate, _start, gain, blob, offset in chunks:
        source = sources[muscle]
        expected = _storable(source.codes[first : first + count])
        try:
            decoded = decode_columns(blob)[_CODES]
        except (StoreError, KeyError) as error:
            raise StoreError(
                f"EMG of {muscle!r} from sample {first} does not decode ({error}): nothing written"
            ) from None
        same = decoded.dtype == expected.dtype and decoded.shape == expected.shape and np.array_equal(
            decoded.view(f"u{decoded.itemsize}"), expected.view(f"u{expected.itemsize}")
        )  # bit for bit
        if not same or (gain, offset) != (source.gain_v, source.offset_v):
            raise StoreError(
                f"EMG of {muscle!r} from sample {first} does not decode to the recording's samples: "
                "nothing written, the stored EMG kept"
            )
    return chunks


def insert_encoded_emg(
    connection: sqlite3.Connection, trial_id: int, chunks: Sequence[EncodedEmgChunk]
) -> None:
    """Insert chunks of :func:`encode_trial_emg` as the trial's (in the caller's transaction)."""
    connection.executemany(_INSERT_SQL, ((trial_id, *chunk) for chunk in chunks))


def delete_trial_emg(connection: sqlite3.Connection, trial_id: int) -> None:
    connection.execute("DELETE FROM emg_chunks WHERE trial_id = ?", (trial_id,))
    if has_table(connection, _LEGACY_TABLE):
        connection.execute("DELETE FROM emg WHERE trial_id = ?", (trial_id,))


def trials_with_emg(connection: sqlite3.Connection) -> list[int]:
    query = "SELECT DISTINCT trial_id FROM emg_chunks"
    if has_table(connection, _LEGACY_TABLE):
        query += " UNION SELECT DISTINCT trial_id FROM emg"
    return sorted(int(row[0]) for row in connection.execute(query))


def emg_muscles(connection: sqlite3.Connection) -> list[str]:
    """Every muscle with stored EMG: the paper's in their order, then the others by name."""
    query = "SELECT DISTINCT muscle FROM emg_chunks"
    if has_table(connection, _LEGACY_TABLE):
        query += " UNION SELECT DISTINCT muscle FROM emg"
    stored = {str(row[0]) for row in connection.execute(query)}
    return [m for m in MUSCLES if m in stored] + sorted(stored - set(MUSCLES))


def iter_trial_emg(connection: sqlite3.Connection, trial_id: int) -> Iterator[pd.DataFrame]:
    """A trial's EMG in consecutive blocks (``time_s`` + one column per muscle, in volts), bounded in
    memory by the chunk size; nothing if the trial has none. All muscles are cut to the shortest.

    Raises
    ------
    StoreError
        A chunk cannot be decoded or the chunks of a muscle do not follow each other (names the trial).
    """
    legacy = has_table(connection, _LEGACY_TABLE) and connection.execute(
        "SELECT 1 FROM emg WHERE trial_id = ? LIMIT 1", (trial_id,)
    ).fetchone() is not None
    table = _LEGACY_TABLE if legacy else "emg_chunks"
    offset = "0.0" if legacy else "offset_v"
    query = f"SELECT muscle, gain, {offset} FROM {table} WHERE trial_id = ?"
    scales = {
        str(muscle): (float(gain), float(offset_v))
        for muscle, gain, offset_v in connection.execute(query, (trial_id,))
    }
    blocks = _legacy_blocks(connection, trial_id) if legacy else _chunk_blocks(connection, trial_id)
    for start, rate, first, codes in blocks:
        length = min(values.size for values in codes.values())
        frame = pd.DataFrame({TRIAL_TIME: start + np.arange(first, first + length) / rate})
        for muscle in _ordered(codes):
            frame[muscle] = decode_source(codes[muscle][:length], *scales[muscle])
        yield frame


def read_trial_emg(connection: sqlite3.Connection, trial_id: int) -> pd.DataFrame | None:
    """A trial's whole EMG (``time_s`` + one column per muscle), or None if it has none."""
    frames = list(iter_trial_emg(connection, trial_id))
    if not frames:
        return None
    return frames[0] if len(frames) == 1 else pd.concat(frames, ignore_index=True)


@dataclass(frozen=True)
class StoredEmgChannel:
    """One muscle's EMG of a trial as the store holds it: ``volts = codes × gain_v + offset_v``."""

    codes: np.ndarray[Any, Any]
    gain_v: float
    offset_v: float
    rate_hz: float
    start_time_s: float


def read_trial_emg_codes(connection: sqlite3.Connection, trial_id: int) -> dict[str, StoredEmgChannel]:
    """A trial's EMG per muscle as stored codes with their scaling (for exports that keep the codes,
    e.g. the BIDS writer's EDF/BDF); empty if the trial has none. Muscles cut to the shortest, as
    :func:`iter_trial_emg` does.
    """
    legacy = has_table(connection, _LEGACY_TABLE) and connection.execute(
        "SELECT 1 FROM emg WHERE trial_id = ? LIMIT 1", (trial_id,)
    ).fetchone() is not None
    table, offset = (_LEGACY_TABLE, "0.0") if legacy else ("emg_chunks", "offset_v")
    scales = {
        str(muscle): (float(gain), float(offset_v))
        for muscle, gain, offset_v in connection.execute(
            f"SELECT muscle, gain, {offset} FROM {table} WHERE trial_id = ?", (trial_id,)
        )
    }
    blocks = list(_legacy_blocks(connection, trial_id) if legacy else _chunk_blocks(connection, trial_id))
    if not blocks:
        return {}
    start, rate = blocks[0][0], blocks[0][1]
    channels = {}
    for muscle in _ordered(blocks[0][3]):
        codes = np.concatenate([block[3][muscle] for block in blocks])
        channels[muscle] = StoredEmgChannel(codes, *scales[muscle], rate_hz=rate, start_time_s=start)
    return channels


Block = tuple[float, float, int, dict[str, np.ndarray[Any, Any]]]


def _chunk_blocks(connection: sqlite3.Connection, trial_id: int) -> Iterator[Block]:
    """Per block of samples: start time, rate, first sample, the codes of every muscle."""
    lengths = dict(
        connection.execute(
            "SELECT muscle, SUM(sample_count) FROM emg_chunks WHERE trial_id = ? GROUP BY muscle", (trial_id,)
        ).fetchall()
    )
    if not lengths:
        return
    length = min(int(n) for n in lengths.values())
    cursor = connection.execute(
        "SELECT first_sample, muscle, sample_count, rate_hz, start_time_s, data FROM emg_chunks "
        "WHERE trial_id = ? AND first_sample < ? ORDER BY first_sample, rowid",
        (trial_id, length),
    )
    current: int | None = None
    codes: dict[str, np.ndarray[Any, Any]] = {}
    rate = start = math.nan
    for first, muscle, count, rate_hz, start_time, blob in cursor:
        if first != current:
            if codes:
                yield start, rate, int(current or 0), codes
            current, codes = first, {}
        rate, start = float(rate_hz), float(start_time)
        try:
            values = decode_columns(blob)[_CODES]
        except (StoreError, KeyError) as error:
            raise StoreError(f"trial {trial_id}: a stored EMG chunk of {muscle!r} is unreadable ({error})") \
                from None
        if values.size != count:
            raise StoreError(f"trial {trial_id}: a stored EMG chunk of {muscle!r} has {values.size} samples, "
                             f"its row says {count}")
        codes[str(muscle)] = values[: length - int(first)]
    if codes:
        yield start, rate, int(current or 0), codes


def _legacy_blocks(connection: sqlite3.Connection, trial_id: int) -> Iterator[Block]:
    """An old store's trial EMG (one raw row per muscle), cut into blocks as the chunks are."""
    rows = connection.execute(
        "SELECT muscle, rate_hz, start_time_s, data FROM emg WHERE trial_id = ? ORDER BY rowid", (trial_id,)
    ).fetchall()
    codes = {str(muscle): np.frombuffer(data, dtype="<i2") for muscle, _rate, _start, data in rows}
    length = min(values.size for values in codes.values())
    for first in range(0, length, EMG_CHUNK_SAMPLES):
        block = {muscle: values[first : first + EMG_CHUNK_SAMPLES] for muscle, values in codes.items()}
        yield float(rows[0][2]), float(rows[0][1]), first, {m: v[: length - first] for m, v in block.items()}


def _ordered(codes: dict[str, np.ndarray[Any, Any]]) -> list[str]:
    """The paper's muscles in their order, then any other in stored order (as the store always did)."""
    return [m for m in MUSCLES if m in codes] + [m for m in codes if m not in MUSCLES]
