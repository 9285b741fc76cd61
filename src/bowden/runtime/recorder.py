"""The crash-safe trial recorder: the loop hands rows to a queue, a writer thread commits them.

The control loop never touches the database: :meth:`Recorder.record` only appends a tuple to a
``queue.SimpleQueue`` (a lock-free C append, well under a microsecond). A writer thread
batches what arrived and commits at least every ``commit_interval_s`` (default 0.1 s, so with the
time a commit takes, well inside the 0.2 s of docs/design.md) into the SQLite store of
:mod:`bowden.store.schema` (WAL journal, ``synchronous=FULL``). A ``kill -9`` therefore loses
only rows not yet committed and never corrupts what was (tested by killing a recording process).

Each commit adds the rows since the last one as a small chunk of ``sample_chunks``. The writer keeps
the rows of the trial's small chunks in memory (at most :data:`~bowden.store.sample_chunks.CHUNK_ROWS`)
and, once they fill a full chunk and when the trial closes, replaces them by full chunks in the
same transaction as that commit's rows: a crash leaves either the small chunks or the full ones,
never both or neither. Each full chunk is decoded and compared with the rows bit for bit before the
small chunks are deleted; one that differs (a fault of the codec) is stored uncompressed instead
(a ``codec_fault`` event says so), and if even that differs the writer fails with the small chunks
kept.

Failures reach the loop: :attr:`Recorder.failure` says why the recording cannot go on — the writer
failed (a full disk, a removed file), or the backlog passed ``max_backlog_rows`` (the disk cannot keep
up). The loop reads it every cycle and, by default, stops safely. The queue's policy: rows are queued
while the writer lives (the loop stops within a cycle of the backlog bound, so the queue stays
bounded); once the writer has died, rows are counted as dropped instead of queued for nobody, and so
are the rows it had not committed and those still queued (:attr:`RecorderStats.dropped_rows`). One
row that cannot be stored (a NaN time, a state that is not a whole number) is not a failure: it is
dropped alone, counted (:attr:`RecorderStats.rejected_rows`) and named in a ``rows_dropped`` event.
:meth:`Recorder.close` then still closes the trial (end time, stop reason) over a fresh connection
when the file lets it, and everything committed before the failure stays in the store.
"""

from __future__ import annotations

import logging
import math
import queue
import sqlite3
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Final, Self

from bowden.contracts import (
    TRIAL_COLUMNS,
    TRIAL_TIME,
)
from bowden.errors import ParameterError, StoreError
from bowden.store.sample_chunks import (
    CHUNK_ROWS,
    Columns,
    EncodedChunk,
    ScreenedRows,
    chunk_row,
    concat_columns,
    delete_chunks,
    faithful_chunk,
    insert_chunk,
    insert_chunks,
    screen_rows,
    split_columns,
)
from bowden.store.schema import configure_connection, create_schema
from bowden.store.trials import TrialInfo, end_trial, insert_events, insert_trial

__all__ = ["Recorder", "RecorderStats", "TrialInfo"]

_log = logging.getLogger(__name__)
_STOP: Final = object()
_MAX_BATCH: Final = 5000


@dataclass
class RecorderStats:
    """What the writer did (read from any thread; written by the writer only)."""

    committed_rows: int = 0
    commits: int = 0
    max_commit_gap_s: float = 0.0  # longest time between two commits while recording
    max_backlog: int = 0
    # Rows handed over that the store will never hold because the writer failed: those it had not
    # committed, those still queued, and those handed over after (counted under _dropped_lock).
    dropped_rows: int = 0
    rejected_rows: int = 0  # rows that could not be stored (NaN time, non-whole state...): dropped alone
    last_committed_time_s: float = math.nan  # loop time of the newest committed row


class Recorder:
    """Records one trial into a study-store file.

    Parameters
    ----------
    path
        The SQLite file (created with the schema if missing).
    trial
        :class:`TrialInfo` of the trial.
    commit_interval_s
        Commit at least this often (s), ≤ 0.2.
    synchronous
        ``"FULL"`` (survives power loss) or ``"NORMAL"`` (survives process crashes).
    on_commit
        Called in the writer thread after each commit with the total committed rows.
    max_backlog_rows
        Rows waiting for the writer beyond which the recording counts as failed (default 5000:
        10 s at 500 Hz, where a healthy writer keeps fewer than a hundred).
    chunk_rows
        Rows of a full chunk of ``sample_chunks`` (default
        :data:`~bowden.store.sample_chunks.CHUNK_ROWS`; tests make it small to merge often).
    """

    def __init__(
        self,
        path: str | Path,
        trial: TrialInfo,
        *,
        commit_interval_s: float = 0.1,
        synchronous: str = "FULL",
        on_commit: Callable[[int], None] | None = None,
        max_backlog_rows: int = 5000,
        chunk_rows: int = CHUNK_ROWS,
    ) -> None:
        if not (math.isfinite(commit_interval_s) and 0.0 < commit_interval_s <= 0.2):
            raise ParameterError(f"commit_interval_s must be in (0, 0.2] s, got {commit_interval_s!r}")
        if isinstance(max_backlog_rows, bool) or not isinstance(max_backlog_rows, int) \
                or max_backlog_rows < 1:
            raise ParameterError(f"max_backlog_rows must be a whole number ≥ 1, got {max_backlog_rows!r}")
        if isinstance(chunk_rows, bool) or not isinstance(chunk_rows, int) or chunk_rows < 1:
            raise ParameterError(f"chunk_rows must be a whole number ≥ 1, got {chunk_rows!r}")
        self.chunk_rows = chunk_rows
        self.path = Path(path)
        self.trial = trial
        self.commit_interval_s = commit_interval_s
        self.synchronous = synchronous
        self.on_commit = on_commit
        self.stats = RecorderStats()
        self.trial_id: int | None = None
        self.max_backlog_rows = max_backlog_rows
        self.error: BaseException | None = None
        self.failure: str | None = None  # why the recording cannot go on; read by the loop
        self.failed_at_utc_s = math.nan  # when it failed (time.time(), like the bus's frame stamps)
        self.trial_closed = False
        self._writer_dead = False
        self._dropped_lock = threading.Lock()  # the loop side and the dying writer both count
        self._queue: queue.SimpleQueue[object] = queue.SimpleQueue()
        self._ready = threading.Event()
        self._thread: threading.Thread | None = None
        self._stop_reason: str | None = None

    # --- loop side -------------------------------------------------------------------------------
    def record(self, row: tuple[float | int, ...]) -> None:
        """Queue one trial-recording row (``contracts.TRIAL_COLUMNS`` order). Never blocks."""
        if self._writer_dead:
            self._count_dropped(1)
            return
        queue_ = self._queue
        queue_.put(row)
        if queue_.qsize() > self.max_backlog_rows and self.failure is None:
            self.failed_at_utc_s = time.time()
            self.failure = (f"{queue_.qsize()} rows waiting to be written to {self.path} "
                            "(the disk cannot keep up)")

    def event(self, time_s: float, kind: str, message: str) -> None:
        """Queue an event (safe stop, fault...) at loop time ``time_s``."""
        self._queue.put(_Event(time_s, kind, message))

    # --- lifecycle -------------------------------------------------------------------------------
    def start(self) -> Self:
        """Open the store, insert the trial and start the writer.

        Raises
        ------
        StoreError
            If the file cannot be opened or written.
        """
        if self._thread is not None:
            return self
        self._thread = threading.Thread(target=self._write, name="recorder", daemon=True)
        self._thread.start()
        self._ready.wait()
        if self.error is not None:
            self._thread.join()
            self._thread = None
            raise StoreError(f"cannot record into {self.path}: {self.error}") from self.error
        return self

    def close(self, stop_reason: str | None = None) -> None:
        """Commit everything queued, close the trial (end time, stop reason) and the file.

        After a writer failure the trial is still closed over a fresh connection if the file takes
        it (:attr:`trial_closed` says whether it did), then the failure is raised.

        Raises
        ------
        StoreError
            If the writer failed (the rows committed before the failure are in the file).
        """
        if self._thread is None:
            return
        self._stop_reason = stop_reason
        self._queue.put(_STOP)
        self._thread.join()
        self._thread = None
        if self.error is not None:
            self._count_dropped(self._drain_queue())  # rows queued after the dying writer emptied it
            self._close_trial_after_failure(stop_reason)
            kept = (f"{self.stats.committed_rows} rows committed before it are kept; the trial was "
                    + ("closed with its stop reason" if self.trial_closed else "left open (no end time)"))
            raise StoreError(f"recording into {self.path} failed: {self.error}; {kept}") from self.error

    def _close_trial_after_failure(self, stop_reason: str | None) -> None:
        reason = f"{stop_reason}; " if stop_reason else ""
        try:
            connection = sqlite3.connect(self.path, timeout=1.0)
            try:
                with connection:
                    end_trial(connection, self.trial_id, f"{reason}recording failed: {self.error}")
            finally:
                connection.close()
        except (sqlite3.Error, OSError) as error:
            _log.error("recorder: could not close trial %s after the failure: %s", self.trial_id, error)
            return
        self.trial_closed = True

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close(stop_reason=None if exc is None else f"error: {exc!r}")

    # --- writer thread ---------------------------------------------------------------------------
    def _open(self) -> sqlite3.Connection:
        connection = sqlite3.connect(self.path, isolation_level="DEFERRED", check_same_thread=True)
        try:
            configure_connection(connection, synchronous=self.synchronous)
            create_schema(connection)
            with connection:
                self.trial_id = insert_trial(connection, self.trial)
        except BaseException:
            connection.close()
            raise
        return connection

    def _write(self) -> None:
        try:
            connection = self._open()
        except (sqlite3.Error, OSError, StoreError) as error:
            self.error = error
            self._ready.set()
            return
        self._ready.set()
        batch: list[tuple[float | int, ...]] = []
        try:
            self._drain(connection, batch)
        except Exception as error:  # whatever kills the writer must reach the loop
            self.error = error
            self._writer_dead = True
            self.failed_at_utc_s = time.time()
            self.failure = f"writing {self.path} failed: {error}"
            if not isinstance(error, sqlite3.Error | OSError | StoreError):
                _log.exception("recorder: the writer failed")
            # The uncommitted batch and the queue behind it will never be written: counted, not lost
            # silently (what was committed before stays in the store).
            self._count_dropped(len(batch) + self._drain_queue())
            _log.error("recorder: %s; %d rows not written", self.failure, self.stats.dropped_rows)
        finally:
            connection.close()

    def _drain_queue(self) -> int:
        """Empty the queue; the number of rows it held."""
        rows = 0
        while True:
            try:
                item = self._queue.get(block=False)
            except queue.Empty:
                return rows
            rows += isinstance(item, tuple)

    def _count_dropped(self, rows: int) -> None:
        with self._dropped_lock:
            self.stats.dropped_rows += rows

    def _drain(self, connection: sqlite3.Connection, samples: list[tuple[float | int, ...]]) -> None:
        """Commit what arrives until the stop; ``samples`` is the batch not yet committed."""
        assert self.trial_id is not None
        chunks = _TrialChunks(self.trial_id, self.chunk_rows)
        columns = len(TRIAL_COLUMNS)
        events: list[tuple[int | None, float | None, str, str]] = []
        get = self._queue.get
        last_commit = time.monotonic()
        stopping = False
        while not stopping:
            timeout = max(0.0, last_commit + self.commit_interval_s - time.monotonic())
            try:
                item = get(timeout=timeout)
            except queue.Empty:
                item = None
            while item is not None:
                if item is _STOP:
                    stopping = True
                elif isinstance(item, _Event):
                    events.append((self.trial_id, item.time_s, item.kind, item.message))
                elif isinstance(item, tuple) and len(item) == columns:
                    samples.append(item)
                else:
                    size = len(item) if isinstance(item, tuple) else item
                    raise StoreError(f"recorder got a row of {size!r} values, expected {columns}")
                if stopping or len(samples) >= _MAX_BATCH:
                    break
                try:
                    item = get(block=False)
                except queue.Empty:
                    item = None
            now = time.monotonic()
            if now - last_commit >= self.commit_interval_s or stopping:
                backlog = self._queue.qsize()
                screened = screen_rows(samples) if samples else None
                batch = screened.columns if screened is not None else None
                if screened is not None and screened.rejected:
                    events.append(self._rejected_event(screened))
                with connection:
                    chunks.commit(connection, batch, final=stopping)
                    if events:
                        insert_events(connection, events)
                    if stopping:
                        end_trial(connection, self.trial_id, self._stop_reason)
                stats = self.stats
                rejected = screened.rejected if screened is not None else 0
                stats.committed_rows += len(samples) - rejected
                stats.rejected_rows += rejected
                if batch is not None:
                    stats.last_committed_time_s = float(batch[TRIAL_TIME][-1])
                stats.commits += 1
                stats.max_commit_gap_s = max(stats.max_commit_gap_s, time.monotonic() - last_commit)
                stats.max_backlog = max(stats.max_backlog, backlog)
                samples.clear()
                events.clear()
                last_commit = time.monotonic()
                if self.on_commit is not None:
                    self.on_commit(stats.committed_rows)

    def _rejected_event(self, screened: ScreenedRows) -> tuple[int | None, float | None, str, str]:
        """The event that says in the trial that rows of a batch could not be stored."""
        message = (f"{screened.rejected} row(s) could not be stored and were dropped; the first: "
                   f"{screened.first_problem}")
        _log.warning("recorder: %s", message)
        time_s = screened.first_time_s if math.isfinite(screened.first_time_s) else None
        return (self.trial_id, time_s, "rows_dropped", message)


class _TrialChunks:
    """The writer's view of its trial's ``sample_chunks``: small chunks merged into full ones."""

    def __init__(self, trial_id: int, chunk_rows: int) -> None:
        self.trial_id = trial_id
        self.chunk_rows = chunk_rows
        self._pending: list[Columns] = []  # the rows of the small chunks, in order
        self._pending_ids: list[int] = []  # their rowids
        self._pending_rows = 0

    def commit(self, connection: sqlite3.Connection, batch: Columns | None, *, final: bool) -> None:
        """Store ``batch`` (inside the caller's transaction); merge when a chunk is full or at the end."""
        rows = 0 if batch is None else len(batch[TRIAL_TIME])
        if batch is not None and not final and self._pending_rows + rows < self.chunk_rows:
            # Small chunks live until the merge: stored raw, so the commit stays short.
            self._pending.append(batch)
            row = chunk_row(self.trial_id, batch, compress=False)
            self._pending_ids.append(insert_chunk(connection, row))
            self._pending_rows += rows
            return
        if batch is None and not (final and len(self._pending) > 1):
            return  # nothing new, and nothing worth merging
        blocks = [*self._pending, *([batch] if batch is not None else [])]
        # Full chunks, then at most one partial one.
        merged = list(split_columns(concat_columns(blocks), self.chunk_rows))
        keep = merged if final else [block for block in merged if len(block[TRIAL_TIME]) == self.chunk_rows]
        # Each new chunk is decoded and compared before the small chunks (the rows' other copy in the
        # store) are deleted.
        full = [(self.trial_id, *self._verified(connection, block)) for block in keep]
        delete_chunks(connection, self._pending_ids)
        insert_chunks(connection, full)
        self._pending, self._pending_ids, self._pending_rows = [], [], 0
        for rest in merged[len(keep):]:  # a partial chunk stays small until it fills
            self._pending = [rest]
            self._pending_ids = [insert_chunk(connection, chunk_row(self.trial_id, rest, compress=False))]
            self._pending_rows = len(rest[TRIAL_TIME])

    def _verified(self, connection: sqlite3.Connection, block: Columns) -> EncodedChunk:
        """A full chunk that decodes to ``block``: compressed, or else raw (said in the trial's
        events); a :class:`StoreError` if neither does (the writer fails; the small chunks stay)."""
        chunk, problem = faithful_chunk(block)
        if problem is not None:
            message = f"{problem}; these {chunk[2]} rows are stored uncompressed instead"
            _log.error("recorder: %s", message)
            insert_events(connection, [(self.trial_id, chunk[0], "codec_fault", message)])
        return chunk


@dataclass(frozen=True, slots=True)
class _Event:
    time_s: float
    kind: str
    message: str
