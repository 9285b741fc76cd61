"""Reading and validating bench recordings (the input of identification, docs/design.md "Contracts").

A bench recording is CSV or Parquet, one row per sample, with exactly the columns
``time_s, motor_torque_nm, motor_velocity_rad_s, tension_n, elevation_rad`` (names from
:mod:`bowden.contracts`) and an optional ``trial`` column. Every problem is reported as a
:class:`bowden.errors.RecordingError` naming the file, the column and the row (rows count data rows
from 1, the first row after a CSV header; for CSV the file line is given too). All problems of a
file are listed together so that one run tells the user everything to fix.

Unit checks catch the usual mistakes: elevation in degrees, torque in mNm, velocity in deg/s or rpm,
time in milliseconds. Their limits live in :class:`RecordingLimits`; the checks themselves in
:mod:`bowden.identify.validation`.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from bowden.contracts import (
    BENCH_COLUMNS,
    BENCH_ELEVATION,
    BENCH_MOTOR_TORQUE,
    BENCH_MOTOR_VELOCITY,
    BENCH_TENSION,
    BENCH_TIME,
    BENCH_TRIAL,
)
from bowden.errors import RecordingError
from bowden.identify.validation import RecordingLimits, validate_bench_frame

__all__ = [
    "BenchRecording",
    "BenchSource",
    "RecordingLimits",
    "bench_recording_from_frame",
    "read_bench_recording",
]

_CSV_SUFFIXES = (".csv", ".csv.gz", ".txt")
_PARQUET_SUFFIXES = (".parquet", ".pq")


@dataclass(frozen=True)
class BenchSource:
    """One file (or in-memory table) of a recording: its name, SHA-256 of its bytes and row count."""

    path: str
    sha256: str
    rows: int


@dataclass(frozen=True, eq=False)
class BenchRecording:
    """A validated bench recording, all sources concatenated (SI units, one entry per sample).

    ``block`` numbers contiguous runs of one trial of one source; filtering never crosses a block.
    ``source_index`` and ``row`` (1-based data row within its source) let later stages name the
    sample they complain about.
    """

    time_s: NDArray[np.float64]
    motor_torque_nm: NDArray[np.float64]
    motor_velocity_rad_s: NDArray[np.float64]
    tension_n: NDArray[np.float64]
    elevation_rad: NDArray[np.float64]
    block: NDArray[np.int64]
    source_index: NDArray[np.int64]
    row: NDArray[np.int64]
    block_labels: tuple[str, ...]
    sources: tuple[BenchSource, ...]

    @property
    def n_samples(self) -> int:
        return int(self.time_s.shape[0])

    def describe_sample(self, index: int) -> str:
        """'row 412 of bench.csv' for sample ``index`` of the concatenated arrays."""
        source = self.sources[int(self.source_index[index])]
        return f"row {int(self.row[index])} of {source.path}"

    def to_frame(self) -> pd.DataFrame:
        """The samples as a table in the contract's column order, with the trial label."""
        frame = pd.DataFrame(
            {
                BENCH_TIME: self.time_s,
                BENCH_MOTOR_TORQUE: self.motor_torque_nm,
                BENCH_MOTOR_VELOCITY: self.motor_velocity_rad_s,
                BENCH_TENSION: self.tension_n,
                BENCH_ELEVATION: self.elevation_rad,
            }
        )
        frame[BENCH_TRIAL] = np.asarray(self.block_labels, dtype=object)[self.block]
        return frame


def _read_table(path: Path) -> tuple[pd.DataFrame, bytes, bool]:
    lower = path.name.lower()
    is_csv = lower.endswith(_CSV_SUFFIXES)
    if not (is_csv or lower.endswith(_PARQUET_SUFFIXES)):
        raise RecordingError(f"bench recording {path}: unknown format '{path.suffix}'; use .csv or .parquet")
    try:
        data = path.read_bytes()
    except OSError as error:
        raise RecordingError(f"bench recording {path}: cannot read it ({error.strerror or error})") from None
    try:
        if is_csv:
            frame = pd.read_csv(path, comment=None, skip_blank_lines=False, low_memory=False)
        else:
            frame = pd.read_parquet(path)
    except (ValueError, OSError, pd.errors.ParserError, pd.errors.EmptyDataError) as error:
        detail = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        kind = "CSV" if is_csv else "Parquet"
        raise RecordingError(f"bench recording {path}: not a readable {kind} file ({detail})") from None
    return frame, data, is_csv


def _assemble(
    parts: Iterable[tuple[dict[str, NDArray[np.float64]], NDArray[np.int64], list[str], BenchSource]],
) -> BenchRecording:
    columns: dict[str, list[NDArray[np.float64]]] = {c: [] for c in BENCH_COLUMNS}
    blocks: list[NDArray[np.int64]] = []
    source_index: list[NDArray[np.int64]] = []
    rows: list[NDArray[np.int64]] = []
    labels: list[str] = []
    sources: list[BenchSource] = []
    for index, (values, block, block_labels, source) in enumerate(parts):
        n = values[BENCH_TIME].shape[0]
        for name in BENCH_COLUMNS:
            columns[name].append(values[name])
        blocks.append(block + len(labels))
        if block_labels == ["all"]:
            labels.append(source.path)
        else:
            labels.extend(f"{source.path} trial {label}" for label in block_labels)
        source_index.append(np.full(n, index, dtype=np.int64))
        rows.append(np.arange(1, n + 1, dtype=np.int64))
        sources.append(source)
    if not sources:
        raise RecordingError("no bench recording given")
    return BenchRecording(
        time_s=np.concatenate(columns[BENCH_TIME]),
        motor_torque_nm=np.concatenate(columns[BENCH_MOTOR_TORQUE]),
        motor_velocity_rad_s=np.concatenate(columns[BENCH_MOTOR_VELOCITY]),
        tension_n=np.concatenate(columns[BENCH_TENSION]),
        elevation_rad=np.concatenate(columns[BENCH_ELEVATION]),
        block=np.concatenate(blocks),
        source_index=np.concatenate(source_index),
        row=np.concatenate(rows),
        block_labels=tuple(labels),
        sources=tuple(sources),
    )


def read_bench_recording(
    paths: str | Path | Sequence[str | Path],
    *,
    limits: RecordingLimits | None = None,
    allow_extra_columns: bool = False,
) -> BenchRecording:
    """Read and validate one or several bench recordings (CSV or Parquet) into one recording.

    Parameters
    ----------
    paths
        One path or several; each file is validated on its own and files never share a filter
        segment.
    limits
        Plausibility limits that catch wrong units (default :class:`RecordingLimits`).
    allow_extra_columns
        Ignore columns outside the contract instead of reporting them.

    Raises
    ------
    RecordingError
        Naming the file, column and row of every problem found.
    """
    limits = limits or RecordingLimits()
    path_list = [Path(paths)] if isinstance(paths, str | Path) else [Path(p) for p in paths]

    def parts() -> Iterable[tuple[dict[str, NDArray[np.float64]], NDArray[np.int64], list[str], BenchSource]]:
        for path in path_list:
            frame, data, is_csv = _read_table(path)
            values, block, labels = validate_bench_frame(
                frame, str(path), is_csv, limits, allow_extra_columns
            )
            source = BenchSource(path=str(path), sha256=hashlib.sha256(data).hexdigest(), rows=frame.shape[0])
            yield values, block, labels, source

    return _assemble(parts())


def bench_recording_from_frame(
    frame: pd.DataFrame,
    *,
    name: str = "<table>",
    limits: RecordingLimits | None = None,
    allow_extra_columns: bool = False,
) -> BenchRecording:
    """Validate an in-memory table (e.g. from the simulated bench) exactly like a file.

    The source's SHA-256 is taken over the column names and pandas' per-row hashes of the values,
    so the same samples always give the same provenance hash.
    """
    limits = limits or RecordingLimits()
    values, block, labels = validate_bench_frame(frame, name, False, limits, allow_extra_columns)
    digest_input = "\x1f".join(map(str, frame.columns)).encode()
    row_hashes = pd.util.hash_pandas_object(frame, index=False).to_numpy()
    digest = hashlib.sha256(digest_input + row_hashes.tobytes()).hexdigest()
    source = BenchSource(path=name, sha256=digest, rows=frame.shape[0])
    return _assemble([(values, block, labels, source)])
