"""Validation of one bench-recording table: every problem named by column and row.

Used by :mod:`bowden.identify.recording` for files and in-memory tables alike. Problems are collected
and raised together as one :class:`bowden.errors.RecordingError`, so that one run tells the user
everything to fix. Rows count data rows from 1 (the first row after a CSV header); for CSV the file
line is given too.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass

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
from bowden.errors import ParameterError, RecordingError

_MAX_LISTED_PROBLEMS = 12


@dataclass(frozen=True, kw_only=True)
class RecordingLimits:
    """Plausibility limits of a bench recording; a value beyond one means wrong units.

    Parameters
    ----------
    max_abs_elevation_rad
        Humeral elevation beyond ±π rad (180°) means the column is in degrees.
    max_abs_motor_torque_nm
        The AK60-6 peaks at 9 Nm (CubeMars AK60-6 specification); beyond 50 Nm the column is in mNm or raw
        counts.
    max_abs_motor_velocity_rad_s
        The AK60-6 is limited to 45–50 rad/s; beyond 100 rad/s the column is in deg/s or rpm.
    max_abs_tension_n
        A textile exosuit cable never carries 2 kN; beyond it the load cell is in g or mN.
    min_sampling_rate_hz
        The 5 Hz zero-phase low-pass needs well above 10 Hz; a slower median rate usually means
        time in milliseconds.
    """

    max_abs_elevation_rad: float = math.pi
    max_abs_motor_torque_nm: float = 50.0
    max_abs_motor_velocity_rad_s: float = 100.0
    max_abs_tension_n: float = 2000.0
    min_sampling_rate_hz: float = 20.0

    def __post_init__(self) -> None:
        for name in (
            "max_abs_elevation_rad",
            "max_abs_motor_torque_nm",
            "max_abs_motor_velocity_rad_s",
            "max_abs_tension_n",
            "min_sampling_rate_hz",
        ):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
                raise ParameterError(f"{name} must be a positive finite number, got {value!r}")


class BenchColumnsError(RecordingError):
    """A bench recording whose columns are not the contract's.

    ``str()`` lists every problem of the file's columns, as any :class:`RecordingError` of a bench
    recording does; ``missing`` and ``unexpected`` keep the columns themselves, and :meth:`one_line`
    says them in one line for a command's refusal.

    Attributes
    ----------
    source
        The file (or table) name.
    missing
        The contract's columns the file lacks, each with the file's column that looks like it (or None).
    unexpected
        The file's columns outside the contract, each with its position (1 the first; empty when they
        are allowed).
    """

    def __init__(
        self,
        message: str,
        *,
        source: str,
        missing: tuple[tuple[str, str | None], ...],
        unexpected: tuple[tuple[int, str], ...],
    ) -> None:
        super().__init__(message)
        self.source = source
        self.missing = missing
        self.unexpected = unexpected

    def one_line(self, ignore_flag: str) -> str:
        """The columns' problem in one line; ``ignore_flag`` (the command's flag that ignores columns
        outside the contract) is named only where giving it would help: nothing is missing."""
        parts = []
        if self.missing:
            names = [name if close is None else f"{name} (found '{close}': rename it?)"
                     for name, close in self.missing]
            parts.append(f"missing column(s) {_first_few(names)}")
        if self.unexpected:
            quoted = [f"'{name}' (column {position})" for position, name in self.unexpected]
            ignore = "" if self.missing else f" (give {ignore_flag} to ignore them)"
            parts.append(f"unexpected column(s) {_first_few(quoted)}{ignore}")
        return f"bench recording {self.source}: {'; '.join(parts)}"


def _first_few(names: list[str], shown: int = 4) -> str:
    """``names`` joined, or the first ``shown`` and "and N more" (never "and 1 more": that one is named)."""
    if len(names) <= shown + 1:
        return ", ".join(names)
    return f"{', '.join(names[:shown])} and {len(names) - shown} more"


class _Problems:
    """Collects every problem of one source, then raises them together."""

    def __init__(self, name: str, is_csv: bool) -> None:
        self.name = name
        self.is_csv = is_csv
        self.items: list[str] = []

    def where(self, row_index: int) -> str:
        row = row_index + 1
        return f"row {row} (line {row + 1})" if self.is_csv else f"row {row}"

    def add(self, message: str) -> None:
        self.items.append(message)

    def message(self) -> str:
        """Every problem collected (the first few dozen), one per line under the source's name."""
        shown = self.items[:_MAX_LISTED_PROBLEMS]
        more = len(self.items) - len(shown)
        lines = "\n".join(f"  - {item}" for item in shown)
        tail = f"\n  ... and {more} more problem(s)" if more else ""
        noun = "problem" if len(self.items) == 1 else "problems"
        return f"bench recording {self.name}: {len(self.items)} {noun}:\n{lines}{tail}"

    def raise_if_any(self) -> None:
        if self.items:
            raise RecordingError(self.message())


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """(first, last) index of every run of True in ``mask``."""
    padded = np.concatenate([[False], mask, [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _check_columns(frame: pd.DataFrame, problems: _Problems, allow_extra_columns: bool) -> pd.DataFrame:
    present = [str(c) for c in frame.columns]
    missing = [c for c in BENCH_COLUMNS if c not in present]
    allowed = (*BENCH_COLUMNS, BENCH_TRIAL)
    extra = [(i + 1, c) for i, c in enumerate(present) if c not in allowed]
    looks_like: list[tuple[str, str | None]] = []
    for name in missing:
        close = difflib.get_close_matches(name, [c for _, c in extra], n=1, cutoff=0.5)
        looks_like.append((name, close[0] if close else None))
        hint = f" (found '{close[0]}': rename it if it holds {name})" if close else ""
        problems.add(f"column {name} is missing{hint}")
    if extra and not allow_extra_columns:
        listed = ", ".join(f"'{c}' (column {i})" for i, c in extra)
        problems.add(
            f"unexpected column(s) {listed}; a bench recording has exactly "
            f"{', '.join(BENCH_COLUMNS)} and optionally {BENCH_TRIAL} (to ignore the others: "
            "allow_extra_columns=True, or --ignore-extra-columns on the command line)"
        )
    duplicated = sorted({c for c in present if present.count(c) > 1})
    for name in duplicated:
        problems.add(f"column {name} appears more than once")
    if not frame.shape[0]:
        problems.add("no data rows")
    unexpected = () if allow_extra_columns else tuple(extra)
    if looks_like or unexpected:
        raise BenchColumnsError(
            problems.message(), source=problems.name, missing=tuple(looks_like), unexpected=unexpected
        )
    problems.raise_if_any()
    keep = [c for c in allowed if c in present]
    return frame.loc[:, keep]


def _numeric_column(frame: pd.DataFrame, name: str, problems: _Problems) -> NDArray[np.float64]:
    raw = frame[name]
    if pd.api.types.is_datetime64_any_dtype(raw) or pd.api.types.is_timedelta64_dtype(raw):
        # Their integer nanoseconds would pass as numbers and fail later as "milliseconds?".
        problems.add(
            f"column {name} holds {raw.dtype} values (dates or durations); a bench recording holds "
            "plain numbers in SI units (for time_s: seconds since the start)"
        )
        # Go on with the seconds they stand for, so the other checks do not report the same problem.
        elapsed = raw - raw.iloc[0] if pd.api.types.is_datetime64_any_dtype(raw) else raw
        return np.asarray(elapsed.dt.total_seconds().to_numpy(dtype=np.float64, na_value=np.nan))
    values = pd.to_numeric(raw, errors="coerce")
    not_number = values.isna().to_numpy() & raw.notna().to_numpy()
    if np.any(not_number):
        first = int(np.flatnonzero(not_number)[0])
        problems.add(
            f"column {name}, {problems.where(first)}: {raw.iloc[first]!r} is not a number"
            + (f" ({int(not_number.sum())} such values)" if not_number.sum() > 1 else "")
        )
    array = values.to_numpy(dtype=np.float64, na_value=np.nan)
    missing = np.isnan(array) & ~not_number
    runs = _runs(missing)
    if runs:
        first_run = runs[0]
        span = (
            problems.where(first_run[0])
            if first_run[0] == first_run[1]
            else f"rows {first_run[0] + 1}–{first_run[1] + 1} ({first_run[1] - first_run[0] + 1} rows)"
        )
        others = ""
        if len(runs) > 1:
            others = f"; {len(runs) - 1} more run(s), {int(missing.sum())} missing values in all"
        problems.add(f"column {name} has missing values (NaN) at {span}{others}; fill or cut them")
    infinite = np.isinf(array)
    if np.any(infinite):
        first = int(np.flatnonzero(infinite)[0])
        problems.add(f"column {name}, {problems.where(first)}: infinite value")
    return array


def _check_units(
    columns: dict[str, NDArray[np.float64]], limits: RecordingLimits, problems: _Problems
) -> None:
    checks = (
        (
            BENCH_ELEVATION,
            limits.max_abs_elevation_rad,
            "rad",
            "the column looks like degrees; convert to radians",
        ),
        (
            BENCH_MOTOR_TORQUE,
            limits.max_abs_motor_torque_nm,
            "Nm",
            "the column looks like mNm (or raw counts); convert to Nm",
        ),
        (
            BENCH_MOTOR_VELOCITY,
            limits.max_abs_motor_velocity_rad_s,
            "rad/s",
            "the column looks like deg/s or rpm; convert to rad/s",
        ),
        (
            BENCH_TENSION,
            limits.max_abs_tension_n,
            "N",
            "the column looks like grams or mN; convert to newtons",
        ),
    )
    for name, limit, unit, advice in checks:
        values = columns[name]
        beyond = np.abs(values) > limit
        if np.any(beyond):
            first = int(np.flatnonzero(beyond)[0])
            problems.add(
                f"column {name}, {problems.where(first)}: {values[first]:.6g} exceeds the plausible "
                f"±{limit:g} {unit}; {advice}"
            )


def _trial_blocks(frame: pd.DataFrame, problems: _Problems) -> tuple[NDArray[np.int64], list[str]]:
    """Number contiguous runs of one trial; a trial that reappears later is an error."""
    n = frame.shape[0]
    if BENCH_TRIAL not in frame.columns:
        return np.zeros(n, dtype=np.int64), ["all"]
    trial = frame[BENCH_TRIAL]
    absent = trial.isna().to_numpy()
    if np.any(absent):
        first = int(np.flatnonzero(absent)[0])
        problems.add(f"column {BENCH_TRIAL}, {problems.where(first)}: missing trial id")
        return np.zeros(n, dtype=np.int64), ["all"]
    labels = trial.astype(str).to_numpy()
    starts = np.concatenate([[0], np.flatnonzero(labels[1:] != labels[:-1]) + 1])
    start_marks = np.zeros(n, dtype=np.int64)
    start_marks[starts] = 1
    block = np.cumsum(start_marks) - 1
    block_labels = [str(labels[s]) for s in starts]
    first_start: dict[str, int] = {}
    for label, start in zip(block_labels, starts, strict=True):
        if label in first_start:
            problems.add(
                f"column {BENCH_TRIAL}, {problems.where(int(start))}: trial {label!r} starts again after "
                f"other trials (it first started at {problems.where(first_start[label])}); keep each "
                "trial's rows together or give the repetition its own trial id"
            )
        else:
            first_start[label] = int(start)
    return block.astype(np.int64), block_labels


def _check_time(
    time_s: NDArray[np.float64],
    block: NDArray[np.int64],
    has_trial: bool,
    limits: RecordingLimits,
    problems: _Problems,
) -> None:
    if time_s.shape[0] < 2 or np.any(np.isnan(time_s)):
        return
    step = np.diff(time_s)
    same_block = block[1:] == block[:-1]
    duplicated = (step == 0.0) & same_block
    backwards = (step < 0.0) & same_block
    if np.any(duplicated):
        first = int(np.flatnonzero(duplicated)[0]) + 1
        problems.add(
            f"column {BENCH_TIME}, {problems.where(first)}: duplicated time {time_s[first]:.6g} s "
            f"(same as the row before; {int(duplicated.sum())} duplicate(s) in all)"
        )
    if np.any(backwards):
        first = int(np.flatnonzero(backwards)[0]) + 1
        hint = "" if has_trial else f"; if the file holds several trials, add a '{BENCH_TRIAL}' column"
        problems.add(
            f"column {BENCH_TIME}, {problems.where(first)}: time goes backwards "
            f"({time_s[first]:.6g} s after {time_s[first - 1]:.6g} s){hint}"
        )
    forward = step[same_block & (step > 0.0)]
    if forward.size:
        median_step = float(np.median(forward))
        if 1.0 / median_step < limits.min_sampling_rate_hz:
            hint = " (is the column in milliseconds? divide by 1000)" if median_step >= 0.5 else ""
            problems.add(
                f"column {BENCH_TIME}: median sampling interval {median_step:.6g} s "
                f"({1.0 / median_step:.3g} Hz) is below the {limits.min_sampling_rate_hz:g} Hz the 5 Hz "
                f"low-pass needs{hint}"
            )


def validate_bench_frame(
    frame: pd.DataFrame, name: str, is_csv: bool, limits: RecordingLimits, allow_extra_columns: bool
) -> tuple[dict[str, NDArray[np.float64]], NDArray[np.int64], list[str]]:
    problems = _Problems(name, is_csv)
    frame = _check_columns(frame, problems, allow_extra_columns)
    columns = {column: _numeric_column(frame, column, problems) for column in BENCH_COLUMNS}
    _check_units(columns, limits, problems)
    block, labels = _trial_blocks(frame, problems)
    _check_time(columns[BENCH_TIME], block, BENCH_TRIAL in frame.columns, limits, problems)
    problems.raise_if_any()
    return columns, block, labels
