"""The recorder: schema, round trip, crash safety under SIGKILL, bad input."""

from __future__ import annotations

import importlib.util
import json
import math
import os
import random
import signal
import sqlite3
import struct
import subprocess
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bowden.errors import ParameterError, StoreError
from bowden.runtime import recorder as recorder_module
from bowden.runtime.recorder import Recorder, TrialInfo
from bowden.store import sample_chunks
from bowden.store.schema import SCHEMA_VERSION

CHILD = Path(__file__).with_name("record_child.py")
_spec = importlib.util.spec_from_file_location("record_child", CHILD)
assert _spec is not None and _spec.loader is not None
record_child = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(record_child)

TRIAL = TrialInfo(participant="P07", condition="support_25", speed="V1", support=0.25,
                  metadata={"rate_hz": 500})


def read_samples(path: Path) -> list[tuple[object, ...]]:
    """Every stored row as ``(trial_id, *TRIAL_COLUMNS)``, None where a value is missing (NaN)."""
    with sqlite3.connect(path) as connection:
        frame = sample_chunks.read_samples(connection)
    return [
        tuple(None if isinstance(v, float) and math.isnan(v) else v for v in row)
        for row in frame.astype(object).itertuples(index=False, name=None)
    ]


def chunk_sizes(connection: sqlite3.Connection) -> list[int]:
    return [n for (n,) in connection.execute("SELECT row_count FROM sample_chunks ORDER BY start_time_s")]


def test_round_trip_with_schema_and_trial(tmp_path: Path) -> None:
    path = tmp_path / "study.db"
    with Recorder(path, TRIAL) as recorder:
        for i in range(1000):
            recorder.record(record_child.row(i))
        recorder.event(0.5, "note", "half way")
    assert recorder.stats.committed_rows == 1000
    rows = read_samples(path)
    assert len(rows) == 1000
    for i, stored in enumerate(rows):
        expected = record_child.row(i)
        assert stored[0] == recorder.trial_id
        assert stored[1:10] == pytest.approx(expected[:9])
        assert stored[10] is None  # NaN tension (no load cell) is NULL
        assert stored[11:] == expected[10:]
    with sqlite3.connect(path) as connection:
        assert connection.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
        assert connection.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
        trial = connection.execute(
            "SELECT participant, condition, speed, support, ended_utc, stop_reason, metadata FROM trials"
        ).fetchone()
        assert trial[:4] == ("P07", "support_25", "V1", 0.25)
        assert trial[4] is not None and trial[5] is None
        assert json.loads(trial[6]) == {"rate_hz": 500}
        assert connection.execute("SELECT time_s, kind, message FROM events").fetchall() == [
            (0.5, "note", "half way")
        ]


def test_second_trial_appends(tmp_path: Path) -> None:
    path = tmp_path / "study.db"
    for _ in range(2):
        with Recorder(path, TRIAL) as recorder:
            recorder.record(record_child.row(0))
    with sqlite3.connect(path) as connection:
        assert connection.execute("SELECT count(*) FROM trials").fetchone()[0] == 2
        assert sample_chunks.trials_with_samples(connection) == [1, 2]


def test_stop_reason_is_stored(tmp_path: Path) -> None:
    path = tmp_path / "study.db"
    recorder = Recorder(path, TRIAL).start()
    recorder.close(stop_reason="IMU: newest sample 51 ms old")
    with sqlite3.connect(path) as connection:
        stored = connection.execute("SELECT stop_reason FROM trials").fetchone()[0]
    assert stored == "IMU: newest sample 51 ms old"


def test_sigkill_keeps_every_committed_sample(tmp_path: Path) -> None:
    path = tmp_path / "study.db"
    progress = tmp_path / "newest"
    # Full chunks of 256 rows: by the kill the writer has merged its small chunks several times.
    chunk_rows = 256
    child = subprocess.Popen([sys.executable, str(CHILD), str(path), str(progress), str(chunk_rows)],
                             stdout=subprocess.PIPE, text=True)
    reported = 0
    try:
        assert child.stdout is not None
        for line in child.stdout:
            reported = int(line.split()[1])
            if reported >= 1500:
                break
        time.sleep(random.uniform(0.0, 0.05))  # anywhere between two commits
        os.kill(child.pid, signal.SIGKILL)
    finally:
        child.kill()
        child.wait(timeout=10)
        if child.stdout is not None:
            child.stdout.close()
    assert child.returncode == -signal.SIGKILL
    (newest,) = struct.unpack("<q", progress.read_bytes())
    with sqlite3.connect(path) as connection:
        assert connection.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        ended = connection.execute("SELECT ended_utc FROM trials").fetchone()[0]
        counts = chunk_sizes(connection)
    assert ended is None  # the trial never closed: the crash is visible
    rows = read_samples(path)
    # Every sample reported committed is there, once, in order, exactly as recorded.
    assert len(rows) >= reported >= 1500
    for i, stored in enumerate(rows):
        expected = record_child.row(i)
        assert stored[1:10] == pytest.approx(expected[:9], abs=0.0)
        assert stored[10] is None  # NaN (no load cell) comes back missing
        assert stored[11:] == expected[10:]
    # At most the last 0.2 s (200 rows at 1 kHz) of what the loop handed over is lost.
    assert 0 <= newest + 1 - len(rows) <= 200, (newest, len(rows))
    # Merged chunks are full; only the rows since the last merge are still in small chunks.
    full = len(rows) // chunk_rows
    assert full >= 5 and counts[:full] == [chunk_rows] * full
    assert sum(counts[full:]) == len(rows) - full * chunk_rows


def test_chunks_are_merged_when_full_and_at_the_end(tmp_path: Path) -> None:
    path = tmp_path / "study.db"
    with Recorder(path, TRIAL, chunk_rows=100, commit_interval_s=0.01) as recorder:
        for i in range(1050):
            recorder.record(record_child.row(i))
            if i % 40 == 0:
                # Several commits, so small chunks are made and merged: wait for each (a busy host's
                # writer thread may sleep longer than any fixed pause).
                deadline = time.monotonic() + 30.0
                while recorder.stats.committed_rows < i + 1 and time.monotonic() < deadline:
                    time.sleep(0.002)
    assert recorder.stats.commits > 10
    with sqlite3.connect(path) as connection:
        counts = chunk_sizes(connection)
    assert counts == [100] * 10 + [50]
    rows = read_samples(path)
    assert [r[1] for r in rows] == [record_child.row(i)[0] for i in range(1050)]


def test_bad_row_fails_loudly(tmp_path: Path) -> None:
    recorder = Recorder(tmp_path / "study.db", TRIAL).start()
    recorder.record((1.0, 2.0))
    with pytest.raises(StoreError, match="expected 12"):
        recorder.close()


def test_one_bad_row_is_dropped_alone_and_counted(tmp_path: Path) -> None:
    """A NaN time, a state that is not a whole number and a value that is not a number each lose
    their own row, never the batch or the queue behind it (issue 27: 2000 rows with one NaN gave 100)."""
    path = tmp_path / "study.db"
    bad = {500: 0, 1200: 10, 1700: 5}  # row index -> the column spoilt
    with Recorder(path, TRIAL, commit_interval_s=0.05) as recorder:
        for i in range(2000):
            row = list(record_child.row(i))
            if i in bad:
                row[bad[i]] = {0: math.nan, 10: 1.5, 5: "0.05 m"}[bad[i]]
            recorder.record(tuple(row))
            if i % 200 == 0:
                time.sleep(0.01)  # several commits
    assert recorder.failure is None
    assert (recorder.stats.committed_rows, recorder.stats.rejected_rows, recorder.stats.dropped_rows) == (
        1997, 3, 0)
    rows = read_samples(path)
    assert [r[1] for r in rows] == [record_child.row(i)[0] for i in range(2000) if i not in bad]
    with sqlite3.connect(path) as connection:
        query = "SELECT time_s, message FROM events WHERE kind = 'rows_dropped'"
        events = connection.execute(query).fetchall()
    assert sum(int(message.split()[0]) for _time, message in events) == 3
    messages = " ".join(message for _time, message in events)
    assert "time_s is nan" in messages


@pytest.mark.parametrize("error", [sqlite3.OperationalError, RuntimeError])
def test_a_dead_writer_counts_every_row_it_will_not_write(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, error: type[Exception]
) -> None:
    """Rows batched or queued when the writer dies, and those handed over after, are counted: what the
    store holds plus what was dropped is what the loop handed over, and the recording has failed
    (a full disk, or a bug: whatever stops the writer)."""
    path = tmp_path / "study.db"
    commits = 0
    commit = recorder_module._TrialChunks.commit

    def failing_commit(self: object, *args: object, **kwargs: object) -> None:
        nonlocal commits
        commits += 1
        if commits == 3:
            time.sleep(0.05)  # rows pile up in the queue behind the failing batch
            raise error("injected: the writer breaks")
        commit(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(recorder_module._TrialChunks, "commit", failing_commit)
    # No backlog bound to meet first: beside busy processes the starved writer once let 5001 rows
    # queue up, and the recording failed on "the disk cannot keep up" before the injected failure.
    recorder = Recorder(path, TRIAL, commit_interval_s=0.02, max_backlog_rows=10**7).start()
    handed = 0
    while recorder.failure is None or handed < 3000:
        recorder.record(record_child.row(handed))
        handed += 1
        if handed % 50 == 0:
            time.sleep(0.002)
        assert handed < 10**6, "the writer's failure never reached the loop"
    assert "injected: the writer breaks" in recorder.failure
    with pytest.raises(StoreError, match="injected"):
        recorder.close(stop_reason="recording failed")
    stored = len(read_samples(path))
    assert stored == recorder.stats.committed_rows > 0
    assert stored + recorder.stats.dropped_rows == handed


def inject_codec_fault(monkeypatch: pytest.MonkeyPatch, faulty: Callable[[int, bool], bool]) -> None:
    """The sample encoder writes one value wrong (+1 N of desired tension) if ``faulty(rows, compress)``."""
    encode = sample_chunks.encode_columns

    def encode_wrongly(columns: Mapping[str, Any], *, compress: bool = True, grids: Any = None) -> bytes:
        if faulty(len(columns["time_s"]), compress):
            columns = dict(columns)
            wrong = np.array(columns["desired_tension_n"], dtype=np.float64)
            wrong[len(wrong) // 2] += 1.0
            columns["desired_tension_n"] = wrong
        return encode(columns, compress=compress, grids=grids)

    monkeypatch.setattr(sample_chunks, "encode_columns", encode_wrongly)


def record_rows(path: Path, n: int) -> Recorder:
    recorder = Recorder(path, TRIAL, chunk_rows=100, commit_interval_s=0.01).start()
    for i in range(n):
        recorder.record(record_child.row(i))
        if i % 40 == 0:
            time.sleep(0.012)  # several commits, so small chunks are made and merged
    return recorder


def test_a_merge_whose_chunk_does_not_decode_keeps_every_row(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The compressed full chunk comes back wrong: it is not stored, the rows go in uncompressed."""
    path = tmp_path / "study.db"
    inject_codec_fault(monkeypatch, lambda _rows, compress: compress)
    record_rows(path, 1050).close()
    assert [r[1:10] for r in read_samples(path)] == [record_child.row(i)[:9] for i in range(1050)]
    with sqlite3.connect(path) as connection:
        assert chunk_sizes(connection) == [100] * 10 + [50]
        faults = connection.execute("SELECT message FROM events WHERE kind = 'codec_fault'").fetchall()
    assert len(faults) == 11
    assert "column 'desired_tension_n' differs from row 50" in faults[0][0]


def test_a_merge_no_encoding_can_store_keeps_the_small_chunks(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Neither encoding of a full chunk comes back right: the writer fails before deleting anything."""
    path = tmp_path / "study.db"
    inject_codec_fault(monkeypatch, lambda rows, _compress: rows == 100)
    recorder = record_rows(path, 1050)
    with pytest.raises(StoreError, match="does not decode to its rows"):
        recorder.close()
    rows = read_samples(path)
    assert 0 < len(rows) == recorder.stats.committed_rows < 100
    assert [r[1:10] for r in rows] == [record_child.row(i)[:9] for i in range(len(rows))]
    assert len(rows) + recorder.stats.dropped_rows == 1050


def test_unwritable_store(tmp_path: Path) -> None:
    with pytest.raises(StoreError, match="cannot record"):
        Recorder(tmp_path / "missing" / "study.db", TRIAL).start()


def test_newer_schema_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "study.db"
    with sqlite3.connect(path) as connection:
        connection.execute(f"PRAGMA user_version={SCHEMA_VERSION + 1}")
    with pytest.raises(StoreError, match="upgrade bowden"):
        Recorder(path, TRIAL).start()


def test_trial_info_validation() -> None:
    with pytest.raises(ParameterError, match="condition"):
        TrialInfo(participant="P1", condition="fifty %")
    with pytest.raises(ParameterError, match="speed"):
        TrialInfo(participant="P1", condition="support_50", speed="fast!")
    with pytest.raises(ParameterError, match="support"):
        TrialInfo(participant="P1", condition="support_50", support=1.5)
    with pytest.raises(ParameterError, match="participant"):
        TrialInfo(participant=" ", condition="support_50")
    with pytest.raises(ParameterError, match="metadata"):
        TrialInfo(participant="P1", condition="support_50", metadata={"x": math.nan})
    with pytest.raises(ParameterError, match="chunk_rows"):
        Recorder("x.db", TrialInfo(participant="P1", condition="no_suit"), chunk_rows=0)
    with pytest.raises(ParameterError, match="commit_interval_s"):
        Recorder("x.db", TrialInfo(participant="P1", condition="no_suit"), commit_interval_s=0.5)
