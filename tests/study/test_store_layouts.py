"""The schema-4 chunk layout of samples and EMG, and stores of the schema-3 row layout still read."""

from __future__ import annotations

import pickle
import sqlite3
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bowden.contracts import MUSCLES, TRIAL_COLUMNS
from bowden.errors import StoreError
from bowden.runtime import Recorder, TrialInfo
from bowden.store.emg_chunks import EMG_CHUNK_SAMPLES
from bowden.store.sample_chunks import CHUNK_ROWS, sample_count
from bowden.store.schema import SCHEMA_VERSION
from bowden.store.study_store import StudyStore
from bowden.store.trial_encoding import encode_trial
from bowden.study.emg.stored import trial_syncs

INFO = TrialInfo(participant="P01", condition="support_50", speed="V2", support=0.5)


def samples(n: int, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    frame = pd.DataFrame({name: rng.normal(size=n) for name in TRIAL_COLUMNS})
    frame["time_s"] = np.arange(n) * 0.002
    frame["controller_state"] = rng.integers(1, 4, n)
    frame["fault_flags"] = rng.integers(0, 2**40, n)
    frame.loc[::7, "tension_n"] = np.nan
    return frame


def emg(n: int, seed: int = 0, muscles: tuple[str, ...] = MUSCLES) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    values = {m: rng.normal(0, 1e-4, n) for m in muscles}
    return pd.DataFrame({"time_s": 0.25 + np.arange(n) / 2000.0, **values})


def test_a_long_trial_spans_chunks_and_comes_back_bit_for_bit(tmp_path: Path) -> None:
    n = 2 * CHUNK_ROWS + 123
    frame, raw = samples(n), emg(2 * EMG_CHUNK_SAMPLES + 77)
    with StudyStore(tmp_path / "study.db") as store:
        trial_id = store.write_trial(INFO, frame, emg=raw)
        chunks = store.read_sql("SELECT row_count FROM sample_chunks ORDER BY start_time_s")
        assert chunks["row_count"].tolist() == [CHUNK_ROWS, CHUNK_ROWS, 123]
        back = store.trial_samples(trial_id)
        pieces = list(store.trial_sample_chunks(trial_id))
        emg_back = store.trial_emg(trial_id)
        assert emg_back is not None
        emg_pieces = list(store.trial_emg_chunks(trial_id))
    for name in TRIAL_COLUMNS:  # float64 bit for bit (NaN included), the codes as int64
        assert back[name].to_numpy().tobytes() == frame[name].to_numpy().tobytes(), name
    assert [len(p) for p in pieces] == [CHUNK_ROWS, CHUNK_ROWS, 123]
    assert [len(p) for p in emg_pieces] == [EMG_CHUNK_SAMPLES, EMG_CHUNK_SAMPLES, 77]
    pd.testing.assert_frame_equal(pd.concat(emg_pieces, ignore_index=True), emg_back)
    # 16-bit codes with one gain per muscle and trial; the time base as before (the rate is measured).
    np.testing.assert_allclose(emg_back["time_s"], raw["time_s"], rtol=0, atol=1e-10)
    for muscle in MUSCLES:
        gain = np.max(np.abs(raw[muscle])) / 32767
        codes = emg_back[muscle].to_numpy() / gain
        np.testing.assert_allclose(codes, np.rint(codes), atol=1e-6)
        assert np.max(np.abs(emg_back[muscle] - raw[muscle])) <= 0.5 * gain * (1 + 1e-9)


def test_a_trial_without_samples_and_bad_samples(tmp_path: Path) -> None:
    with StudyStore(tmp_path / "study.db") as store:
        empty = store.write_trial(INFO, samples(0))
        assert store.trial_samples(empty).empty and list(store.trial_samples(empty)) == list(TRIAL_COLUMNS)
        bad = samples(10)
        bad.loc[3, "controller_state"] = np.nan
        with pytest.raises(StoreError, match="controller_state is missing"):
            store.write_trial(INFO, bad)
        bad = samples(10)
        bad["fault_flags"] = 0.5
        with pytest.raises(StoreError, match="fault_flags must hold whole numbers"):
            store.write_trial(INFO, bad)
        assert len(store.completed_trials()) == 1


# The layout of schema 3, as bowden 0.x wrote it: one row per cycle, one raw EMG row per muscle.
_V3_DDL = (
    """CREATE TABLE trials (id INTEGER PRIMARY KEY, participant TEXT NOT NULL, condition TEXT NOT NULL,
    speed TEXT, support REAL, started_utc TEXT NOT NULL, ended_utc TEXT, stop_reason TEXT,
    metadata TEXT NOT NULL DEFAULT '{}') STRICT""",
    "CREATE TABLE samples (trial_id INTEGER NOT NULL REFERENCES trials(id), "
    + ", ".join(
        f"{name} {'INTEGER NOT NULL' if name in ('controller_state', 'fault_flags') else 'REAL'}"
        + (" NOT NULL" if name == "time_s" else "")
        for name in TRIAL_COLUMNS
    )
    + ") STRICT",
    "CREATE INDEX samples_by_trial_time ON samples (trial_id, time_s)",
    """CREATE TABLE events (trial_id INTEGER NOT NULL REFERENCES trials(id), time_s REAL,
    kind TEXT NOT NULL, message TEXT NOT NULL) STRICT""",
    """CREATE TABLE emg (trial_id INTEGER NOT NULL REFERENCES trials(id), muscle TEXT NOT NULL,
    rate_hz REAL NOT NULL, start_time_s REAL NOT NULL, gain REAL NOT NULL, data BLOB NOT NULL,
    PRIMARY KEY (trial_id, muscle)) STRICT""",
)


def v3_store(path: Path, frame: pd.DataFrame, raw: pd.DataFrame) -> Path:
    """A schema-3 store holding one finished and one unfinished trial, written as bowden 0.x did."""
    with sqlite3.connect(path) as db:
        for ddl in _V3_DDL:
            db.execute(ddl)
        for trial_id, ended in ((1, "2025-01-01T00:01:00+00:00"), (2, None)):
            db.execute(
                "INSERT INTO trials VALUES (?, 'P01', 'support_50', 'V2', 0.5, "
                "'2025-01-01T00:00:00+00:00', ?, NULL, ?)",
                (trial_id, ended, '{"recorded_by": "bowden study", "backend": "sim"}'),
            )
            rows = frame.loc[:, list(TRIAL_COLUMNS)].astype(object).where(frame.notna(), None)
            db.executemany(
                f"INSERT INTO samples VALUES ({', '.join('?' * (len(TRIAL_COLUMNS) + 1))})",
                ((trial_id, *row) for row in rows.itertuples(index=False, name=None)),
            )
        for muscle in MUSCLES:
            gain = float(np.max(np.abs(raw[muscle]))) / 32767.0
            data = np.rint(raw[muscle].to_numpy() / gain).astype("<i2").tobytes()
            db.execute("INSERT INTO emg VALUES (1, ?, 2000.0, 0.25, ?, ?)", (muscle, gain, data))
        db.execute("PRAGMA user_version=3")
    db.close()
    return path


def test_a_schema_3_store_opens_reads_exports_and_takes_new_trials(tmp_path: Path) -> None:
    frame, raw = samples(3000), emg(40000)
    path = v3_store(tmp_path / "old.db", frame, raw)
    with StudyStore(tmp_path / "new.db") as new:  # the same trial in today's layout
        new.write_trial(INFO, frame, emg=raw)
        expected_emg = new.trial_emg(1)
    with StudyStore(path) as store:
        assert [t.trial_id for t in store.completed_trials()] == [1]
        pd.testing.assert_frame_equal(store.trial_samples(1), frame.loc[:, list(TRIAL_COLUMNS)],
                                      check_dtype=False)
        assert store.trial_samples(1)["fault_flags"].dtype == np.int64
        old_emg = store.trial_emg(1)
        assert old_emg is not None and expected_emg is not None
        pd.testing.assert_frame_equal(old_emg, expected_emg)
        assert store.trials_with_samples() == [1, 2] and store.trials_with_emg() == [1]
        assert store.last_sample_times() == {1: frame["time_s"].iloc[-1], 2: frame["time_s"].iloc[-1]}
        assert trial_syncs(store) == {}  # no sync events, but the query runs on the old table
        exported = pd.read_parquet(store.export(tmp_path / "out")[2])
        assert len(exported) == 2 * len(frame)
        # A new trial goes to the chunks; the unfinished old one is discarded with its rows.
        third = store.write_trial(INFO, frame.iloc[:100])
        assert store.discard_unfinished_trials() == 1
        assert sample_count(store._db) == len(frame) + 100
        assert store.trials_with_samples() == [1, third]
    with Recorder(path, INFO) as recorder:  # the live recorder writes into the old store as well
        recorder.record(tuple(float(v) for v in frame.iloc[0]))
    with StudyStore(path) as store:
        assert store.trials_with_samples() == [1, third, recorder.trial_id]
        assert store.read_sql("PRAGMA user_version").iloc[0, 0] == SCHEMA_VERSION


def test_a_trial_encoded_elsewhere_is_stored_as_write_trial_stores_it(tmp_path: Path) -> None:
    # The study's workers encode their trials and send the chunks (pickled) to the one writer.
    frame, raw = samples(CHUNK_ROWS + 50, seed=3), emg(EMG_CHUNK_SAMPLES + 9, seed=3)
    encoded = pickle.loads(pickle.dumps(encode_trial(frame, raw)))
    with StudyStore(tmp_path / "direct.db") as direct, StudyStore(tmp_path / "encoded.db") as elsewhere:
        first = direct.write_trial(INFO, frame, emg=raw)
        second = elsewhere.write_encoded_trial(INFO, encoded)
        for table in ("sample_chunks", "emg_chunks"):
            query = f"SELECT * FROM {table} ORDER BY 1, 2, 3"
            pd.testing.assert_frame_equal(direct.read_sql(query), elsewhere.read_sql(query))
        pd.testing.assert_frame_equal(direct.trial_samples(first), elsewhere.trial_samples(second))
    assert encode_trial(frame).emg == []  # no sEMG: no chunks
    with pytest.raises(StoreError, match="evenly spaced"):
        encode_trial(frame, raw.assign(time_s=raw["time_s"] ** 2))
