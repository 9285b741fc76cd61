"""The bench recording written stroke by stroke: crash-safe and resumable.

``bowden bench run`` writes the bench-recording contract (``contracts.BENCH_COLUMNS`` and ``trial``,
one trial per stroke) that ``bowden identify`` reads as it is, and beside it a device log with what
the contract leaves out (the mannequin motor, the commands, the phase of each stroke).

A stroke's rows are appended to both files only when the stroke is complete, then flushed to disk
(``fsync``), and only then is the journal (``<recording>.journal``, JSON, replaced atomically)
told the stroke is done and how long the files are. A crash or a safe stop at any moment therefore
leaves complete strokes on disk; resuming truncates whatever a crash left after the last journalled
stroke and goes on with the next stroke. The journal also keeps the protocol, so a resume with other
numbers is refused rather than mixed into one recording; what the run has learned about the bench
(:mod:`bowden.runtime.bench_ends`), so a resume starts as informed as the run it continues; and the
time of the last row of either file, so a resumed run's times continue after everything written
(the device log holds the unrecorded moves and the stroke under way at a stop). A recording that
holds no stroke yet (the bench stopped before its first) is continued by the next run, with or
without ``--resume``, and with the protocol of that run: nothing of it blocks a new start, and its
device log is kept.

A ``.parquet`` recording is written as CSV while the run goes on (``<name>.parquet.partial.csv``:
Parquet cannot be appended to) and converted once the protocol is complete.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np
from numpy.typing import NDArray

from bowden._atomic_file import write_text_atomically
from bowden.contracts import BENCH_COLUMNS, BENCH_TRIAL
from bowden.errors import OutputFileError, RecordingError

_log = logging.getLogger(__name__)

RECORDING_COLUMNS = (*BENCH_COLUMNS, BENCH_TRIAL)
LOG_COLUMNS = (
    "time_s", "trial", "phase", "spool_target_rad", "spool_velocity_target_rad_s", "spool_position_rad",
    "mannequin_torque_command_nm", "mannequin_torque_nm", "mannequin_position_rad",
    "mannequin_velocity_rad_s",
)
_JOURNAL_VERSION = 1
# The later segments of the protocol (docs/identification.md, "The protocol, exactly"), each its own
# CSV beside the recording (``<stem>.<name>.csv``), with its own columns.
LATENCY_COLUMNS = ("time_s", "elevation_rad", "mannequin_elevation_rad")
STUDY_COLUMNS = (
    "time_s", "block", "support", "speed", "compensation", "cycle_phase", "motor_torque_nm",
    "motor_velocity_rad_s", "tension_n", "elevation_rad", "mannequin_elevation_rad",
    "reference_elevation_rad", "law_tension_n", "command_tension_n", "fit", "candidate",
)
SEGMENT_COLUMNS = {"latency": LATENCY_COLUMNS, "study": STUDY_COLUMNS}
_SEGMENT_INTEGERS = {"latency": (), "study": (1, 3, 4, 14, 15)}


@dataclass(frozen=True)
class ResumePoint:
    """Where a recording stands: strokes complete, the time (s) of the last row written to either
    file, and what the run learned about the bench (:meth:`bowden.runtime.bench_ends.LearnedEnds.to_json`)."""

    strokes_done: int
    last_time_s: float
    learned: dict[str, Any] = field(default_factory=dict)


def journal_path(recording: str | Path) -> Path:
    """The journal of the bench recording ``recording``: ``<recording>.journal``."""
    path = Path(recording)
    return path.with_name(path.name + ".journal")


def read_journal(recording: str | Path) -> dict[str, Any] | None:
    """The journal of the bench recording ``recording`` (strokes done, the protocol's numbers, …), or
    None when it has none; a file that is not a journal is a :class:`RecordingError`."""
    path = journal_path(recording)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    except OSError as error:
        raise RecordingError(f"cannot read {path}: {error.strerror or error}") from None
    try:
        journal: dict[str, Any] = json.loads(text)
        if journal.get("version") != _JOURNAL_VERSION:
            raise ValueError(f"version {journal.get('version')!r}")
        for key in ("strokes_done", "data_bytes", "log_bytes", "last_time_s"):
            if not isinstance(journal.get(key), int | float):
                raise ValueError(f"no {key}")
    except (ValueError, AttributeError) as error:
        raise RecordingError(f"{path} is not a bench-run journal ({error})") from None
    return journal


def journal_model(journal: dict[str, Any] | None) -> str | None:
    """The digest of the model a ``bench validate`` run's blocks ran, as its journal keeps it (None
    for ``bench run``'s journal, which keeps none, or a protocol that is not a mapping)."""
    protocol = None if journal is None else journal.get("protocol")
    model = protocol.get("model") if isinstance(protocol, dict) else None
    return None if model is None else str(model)


class BenchRecordingWriter:
    """Appends complete strokes to a bench recording and its device log (a context manager).

    Parameters
    ----------
    path
        The recording (``.csv`` or ``.parquet``); the device log is ``<stem>.log.csv`` beside it.
    protocol
        The protocol's numbers (JSON-serialisable), kept in the journal and compared on resume.
    resume
        Continue a recording whose journal says it is incomplete; without it an existing recording
        is refused (nothing is overwritten).
    """

    def __init__(self, path: str | Path, protocol: dict[str, Any], *, resume: bool = False) -> None:
        self.path = Path(path)
        suffix = self.path.suffix.lower()
        if suffix not in (".csv", ".parquet"):
            raise OutputFileError(f"cannot tell the format of {self.path}: use a .csv or .parquet extension")
        folder = self.path.absolute().parent
        if not folder.is_dir():
            reason = "is not a directory" if folder.exists() else "does not exist"
            raise OutputFileError(f"cannot write the bench recording to {self.path}: "
                                  f"the folder {folder} {reason}")
        self._parquet = suffix == ".parquet"
        self.data_path = self.path.with_name(self.path.name + ".partial.csv") if self._parquet else self.path
        self.log_path = self.path.with_name(self.path.stem + ".log.csv")
        self.journal_path = journal_path(self.path)
        self.protocol = protocol
        self._data: TextIO | None = None
        self._log: TextIO | None = None
        self._learned: dict[str, Any] = {}
        self._last_log_time_s = 0.0
        self._segments: dict[str, TextIO] = {}
        self._segment_bytes: dict[str, int] = {}
        self.resume_point = self._open(resume)

    def segment_path(self, name: str) -> Path:
        """The file of a later segment (``"latency"``, ``"study"``): ``<stem>.<name>.csv``."""
        return self.path.with_name(f"{self.path.stem}.{name}.csv")

    # --- opening ---------------------------------------------------------------------------------
    def _open(self, resume: bool) -> ResumePoint:
        journal = self._read_journal()
        if journal is None:
            existing = [p for p in (self.path, self.data_path, self.log_path) if p.exists()]
            if existing:
                raise OutputFileError(f"{existing[0]} exists and has no journal of an unfinished bench run: "
                                      "choose another file name (nothing is overwritten)")
            if resume:
                raise OutputFileError(f"nothing to resume: {self.journal_path} does not exist")
            self._start_files()
            return ResumePoint(0, 0.0)
        empty = not journal.get("complete") and journal["strokes_done"] == 0
        if empty:
            journal["protocol"] = self.protocol  # nothing recorded follows the earlier protocol
        elif not resume:
            state = "complete" if journal.get("complete") else "unfinished"
            raise OutputFileError(f"{self.path} is an {state} bench recording: "
                                  + ("choose another file name" if journal.get("complete")
                                     else "add --resume to continue it, or choose another file name"))
        if journal.get("complete"):
            raise OutputFileError(f"{self.path} is already complete ({journal['strokes_done']} strokes)")
        started_model = journal_model(journal)
        if started_model != self.protocol.get("model"):
            raise OutputFileError(f"cannot resume {self.path} with another model: its blocks ran the one "
                                  f"whose coefficients hash to {str(started_model)[:12]}, this one's hash to "
                                  f"{str(self.protocol.get('model'))[:12]}; validate it into another file")
        if journal.get("protocol") != self.protocol:
            raise OutputFileError(f"cannot resume {self.path} with another protocol: it was started with "
                                  f"{journal.get('protocol')}, this run has {self.protocol}")
        for path, size in ((self.data_path, journal["data_bytes"]), (self.log_path, journal["log_bytes"])):
            try:
                if path.stat().st_size < size:
                    raise RecordingError(f"{path} is shorter than its journal says ({path.stat().st_size} "
                                         f"< {size} bytes): it was changed after the run stopped")
                with path.open("r+b") as handle:  # drop what a crash left after the last stroke
                    handle.truncate(size)
            except FileNotFoundError:
                raise RecordingError(f"{path} is missing: the journal says it holds "
                                     f"{journal['strokes_done']} strokes") from None
        self._resume_segments(journal)
        self._data = self.data_path.open("a", encoding="utf-8", newline="")
        self._log = self.log_path.open("a", encoding="utf-8", newline="")
        learned = journal.get("learned", {})
        self._learned = learned if isinstance(learned, dict) else {}
        self._last_log_time_s = float(journal.get("last_log_time_s", journal["last_time_s"]))
        last = max(float(journal["last_time_s"]), self._last_log_time_s)
        return ResumePoint(int(journal["strokes_done"]), last, self._learned)

    def _resume_segments(self, journal: dict[str, Any]) -> None:
        """Cut each segment file back to its journalled length (a segment file the journal does not
        know holds no complete block: it is removed)."""
        known = journal.get("segments", {})
        for name in SEGMENT_COLUMNS:
            path = self.segment_path(name)
            size = known.get(name) if isinstance(known, dict) else None
            if not isinstance(size, int):
                path.unlink(missing_ok=True)
                continue
            try:
                with path.open("r+b") as handle:
                    header = handle.readline().decode("utf-8", "replace").strip()
                    handle.truncate(size)
            except FileNotFoundError:
                raise RecordingError(f"{path} is missing: the journal says it holds {size} bytes") from None
            if header != ",".join(SEGMENT_COLUMNS[name]):
                # Written by a bowden with other columns (the study-like segment's fit and candidate
                # came later): rows of two layouts in one file would be misread.
                raise RecordingError(f"{path} has other columns than this bowden writes ({header}): "
                                     "finish it with the version that started it, or start a new recording")
            self._segment_bytes[name] = size
            self._segments[name] = path.open("a", encoding="utf-8", newline="")

    def _read_journal(self) -> dict[str, Any] | None:
        return read_journal(self.path)

    def _start_files(self) -> None:
        try:
            self._data = self.data_path.open("x", encoding="utf-8", newline="")
            self._log = self.log_path.open("x", encoding="utf-8", newline="")
            self._data.write(",".join(RECORDING_COLUMNS) + "\n")
            self._log.write(",".join(LOG_COLUMNS) + "\n")
        except OSError as error:
            self.close()
            raise OutputFileError(f"cannot create the bench recording {self.path}: "
                                  f"{error.strerror or error}") from None
        self._sync(0, 0.0, complete=False)

    # --- writing ---------------------------------------------------------------------------------
    def write_stroke(self, rows: NDArray[np.float64], log_rows: NDArray[np.float64],
                     strokes_done: int, learned: dict[str, Any] | None = None) -> None:
        """Append one complete stroke (``rows``: RECORDING_COLUMNS, ``log_rows``: LOG_COLUMNS) and
        journal that ``strokes_done`` strokes are now on disk, with what the run has ``learned``
        (JSON-serialisable; kept as it was if None).

        Raises
        ------
        OutputFileError
            If the disk refuses the data; the strokes journalled before stay valid.
        """
        if rows.ndim != 2 or rows.shape[1] != len(RECORDING_COLUMNS) or rows.shape[0] == 0:
            raise RecordingError(f"a stroke needs rows of {len(RECORDING_COLUMNS)} columns, got {rows.shape}")
        if log_rows.ndim != 2 or log_rows.shape[1] != len(LOG_COLUMNS):
            raise RecordingError(f"a stroke's log needs {len(LOG_COLUMNS)} columns, got {log_rows.shape}")
        try:
            _append(self._require(self._data), rows, integer_columns=(len(RECORDING_COLUMNS) - 1,))
            _append(self._require(self._log), log_rows, integer_columns=(1, 2))
        except OSError as error:
            self._cut_back()
            raise OutputFileError(f"cannot write the bench recording {self.path}: "
                                  f"{error.strerror or error}") from None
        if learned is not None:
            self._learned = learned
        self._note_log_time(log_rows)
        self._sync(strokes_done, float(rows[-1, 0]), complete=False)

    def write_segment(self, name: str, rows: NDArray[np.float64], log_rows: NDArray[np.float64],
                      units_done: int) -> None:
        """Append one complete block of a later segment (``name``: ``"latency"`` or ``"study"``; its
        rows in :data:`SEGMENT_COLUMNS` order) to its own file, its log to the device log, and journal
        that ``units_done`` units of the protocol (strokes, then blocks) are on disk.

        Raises
        ------
        OutputFileError
            If the disk refuses the data; what was journalled before stays valid.
        """
        columns = SEGMENT_COLUMNS[name]
        if rows.ndim != 2 or rows.shape[1] != len(columns) or rows.shape[0] == 0:
            raise RecordingError(f"a {name} block needs rows of {len(columns)} columns, got {rows.shape}")
        try:
            handle = self._segments.get(name)
            if handle is None:
                handle = self._segments[name] = self.segment_path(name).open("w", encoding="utf-8",
                                                                              newline="")
                handle.write(",".join(columns) + "\n")
            _append(handle, rows, integer_columns=_SEGMENT_INTEGERS[name])
            if log_rows.shape[0]:
                _append(self._require(self._log), log_rows, integer_columns=(1, 2))
        except OSError as error:
            self._cut_back()
            raise OutputFileError(f"cannot write the {name} segment {self.segment_path(name)}: "
                                  f"{error.strerror or error}") from None
        self._note_log_time(log_rows)
        journal = self._read_journal()
        last = float(journal["last_time_s"]) if journal is not None else 0.0
        self._sync(units_done, max(last, float(rows[-1, 0])), complete=False)

    def _note_log_time(self, log_rows: NDArray[np.float64]) -> None:
        if log_rows.shape[0]:
            self._last_log_time_s = max(self._last_log_time_s, float(log_rows[-1, 0]))

    def _cut_back(self) -> None:
        """After a failed write, cut both files back to their journalled length, so that the
        recording on disk stays whole strokes (``bowden identify`` reads it as it is)."""
        journal = self._read_journal()
        if journal is None:
            return
        known = journal.get("segments", {})
        segments = [(handle, known.get(name, 0)) for name, handle in self._segments.items()]
        for handle, size in ((self._data, journal["data_bytes"]), (self._log, journal["log_bytes"]),
                             *segments):
            if handle is None or handle.closed:
                continue
            with contextlib.suppress(OSError, ValueError):
                handle.flush()
            with contextlib.suppress(OSError, ValueError):
                handle.seek(size)
                handle.truncate(size)

    def write_log(self, log_rows: NDArray[np.float64]) -> None:
        """Append the log of a stroke that did not complete (a fault, an interruption): kept for the
        diagnosis, and by a resume; the recording itself gets only complete strokes."""
        if log_rows.ndim != 2 or log_rows.shape[1] != len(LOG_COLUMNS) or log_rows.shape[0] == 0:
            return
        journal = self._read_journal()
        assert journal is not None
        try:
            _append(self._require(self._log), log_rows, integer_columns=(1, 2))
        except OSError as error:
            self._cut_back()
            raise OutputFileError(f"cannot write the bench log {self.log_path}: "
                                  f"{error.strerror or error}") from None
        self._note_log_time(log_rows)
        self._sync(int(journal["strokes_done"]), float(journal["last_time_s"]), complete=False)

    def finish(self) -> Path:
        """Mark the recording complete (a ``.parquet`` one is converted now); returns its path."""
        journal = self._read_journal()
        assert journal is not None
        self.close()
        if self._parquet:
            import pandas as pd

            try:
                pd.read_csv(self.data_path).to_parquet(self.path, index=False)
            except (OSError, ValueError, ImportError) as error:
                raise OutputFileError(f"cannot write {self.path} (the CSV {self.data_path} is kept): "
                                      f"{error}") from None
            self.data_path.unlink()
        journal["complete"] = True
        write_text_atomically(self.journal_path, json.dumps(journal, indent=1) + "\n", durable=True)
        return self.path

    def _sync(self, strokes_done: int, last_time_s: float, *, complete: bool) -> None:
        data, log = self._require(self._data), self._require(self._log)
        try:
            for handle in (data, log, *self._segments.values()):
                handle.flush()
                os.fsync(handle.fileno())
            self._segment_bytes.update({name: handle.tell() for name, handle in self._segments.items()})
            journal = {
                "version": _JOURNAL_VERSION, "recording": self.path.name, "protocol": self.protocol,
                "strokes_done": strokes_done, "last_time_s": last_time_s, "complete": complete,
                "data_bytes": data.tell(), "log_bytes": log.tell(),
                "last_log_time_s": self._last_log_time_s, "learned": self._learned,
                "segments": self._segment_bytes,
            }
            write_text_atomically(self.journal_path, json.dumps(journal, indent=1) + "\n", durable=True)
        except OSError as error:
            raise OutputFileError(f"cannot write the bench recording {self.path}: "
                                  f"{error.strerror or error}") from None

    @staticmethod
    def _require(handle: TextIO | None) -> TextIO:
        if handle is None:
            raise RecordingError("the bench recording is closed")
        return handle

    def discard_if_empty(self) -> bool:
        """Remove the files this writer created if nothing but their headers was written (the bench
        never ran: a device did not open); True if removed. A resumed recording is never removed."""
        journal = self._read_journal()
        if journal is None or self.resume_point.strokes_done or journal["strokes_done"]:
            return False
        headers = (len(",".join(RECORDING_COLUMNS)) + 1, len(",".join(LOG_COLUMNS)) + 1)
        if (journal["data_bytes"], journal["log_bytes"]) != headers:
            return False
        self.close()
        for path in (self.data_path, self.log_path, self.journal_path):
            path.unlink(missing_ok=True)
        return True

    def close(self) -> None:
        """Close the files (what is journalled stays; nothing else is written)."""
        for handle in (self._data, self._log, *self._segments.values()):
            if handle is not None and not handle.closed:
                try:
                    handle.close()
                except OSError as error:
                    # What a failed write left in the buffer; the journal never counted it.
                    _log.warning("bench recording: closing %s: %s", handle.name, error.strerror or error)
        self._data = self._log = None
        self._segments = {}

    def __enter__(self) -> BenchRecordingWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _append(handle: TextIO, rows: NDArray[np.float64], integer_columns: Sequence[int]) -> None:
    formats = ["%d" if i in integer_columns else "%.9g" for i in range(rows.shape[1])]
    np.savetxt(handle, rows, fmt=formats, delimiter=",")
