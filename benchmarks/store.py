"""Size of the default study's store against the issue's 250 MB target, before and after chunking.

Run: python benchmarks/store.py [--participants N] [--store study.db] [--legacy-copy old.db]
Runs the study (or takes a store), prints its size, each table's share, each sample column's share
with the codec filter that stored it, and the codec's speed on the store's own chunks (ms per MB of
decoded values: the encoder runs in the recording process and in `bowden study`'s trials stage);
then writes the same trials in the schema-3 layout (one row per control cycle, raw 16-bit EMG; what
bowden wrote before the chunks) and prints that size too: before/after from one run.
"""

from __future__ import annotations

import argparse
import sqlite3
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

from bowden.contracts import TRIAL_COLUMNS
from bowden.store.column_codec import column_sizes, decode_columns, encode_columns
from bowden.store.sensor_grids import KNOWN_GRIDS
from bowden.store.study_store import StudyStore

TARGET_MB = 250.0

# Schema 3's sample and EMG tables (with its index), as src/bowden/store/schema.py had them.
_V3_DDL = (
    "CREATE TABLE trials (id INTEGER PRIMARY KEY, participant TEXT NOT NULL, condition TEXT NOT NULL, "
    "speed TEXT, support REAL, started_utc TEXT NOT NULL, ended_utc TEXT, stop_reason TEXT, "
    "metadata TEXT NOT NULL DEFAULT '{}') STRICT",
    "CREATE TABLE samples (trial_id INTEGER NOT NULL REFERENCES trials(id), "
    + ", ".join(
        f"{n} {'INTEGER NOT NULL' if n in ('controller_state', 'fault_flags') else 'REAL'}"
        + (" NOT NULL" if n == "time_s" else "")
        for n in TRIAL_COLUMNS
    )
    + ") STRICT",
    "CREATE INDEX samples_by_trial_time ON samples (trial_id, time_s)",
    "CREATE TABLE events (trial_id INTEGER NOT NULL, time_s REAL, kind TEXT NOT NULL, "
    "message TEXT NOT NULL) STRICT",
    "CREATE TABLE emg (trial_id INTEGER NOT NULL REFERENCES trials(id), muscle TEXT NOT NULL, "
    "rate_hz REAL NOT NULL, start_time_s REAL NOT NULL, gain REAL NOT NULL, data BLOB NOT NULL, "
    "PRIMARY KEY (trial_id, muscle)) STRICT",
)


def write_legacy_copy(store_path: Path, legacy: Path) -> None:
    """The trials, samples, events and EMG of ``store_path`` in the schema-3 layout at ``legacy``."""
    legacy.unlink(missing_ok=True)
    db = sqlite3.connect(legacy)
    db.execute("PRAGMA journal_mode=WAL")
    for ddl in _V3_DDL:
        db.execute(ddl)
    insert = f"INSERT INTO samples VALUES ({', '.join('?' * (len(TRIAL_COLUMNS) + 1))})"
    with StudyStore(store_path) as store:
        trials = store.read_sql("SELECT * FROM trials ORDER BY id")
        db.executemany("INSERT INTO trials VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                       trials.astype(object).where(trials.notna(), None).itertuples(index=False, name=None))
        events = store.read_sql("SELECT trial_id, time_s, kind, message FROM events")
        db.executemany("INSERT INTO events VALUES (?, ?, ?, ?)",
                       events.astype(object).where(events.notna(), None).itertuples(index=False, name=None))
        for trial_id in store.trials_with_samples():
            frame = store.trial_samples(trial_id)
            rows = frame.astype(object).where(frame.notna(), None)
            db.executemany(insert, ((trial_id, *r) for r in rows.itertuples(index=False, name=None)))
            db.commit()
        for trial_id in store.trials_with_emg():
            emg = store.trial_emg(trial_id)
            assert emg is not None
            rate = 1.0 / float(np.median(np.diff(emg["time_s"])))
            for muscle in [m for m in emg.columns if m != "time_s"]:
                values = emg[muscle].to_numpy()
                peak = float(np.max(np.abs(values)))
                gain = peak / 32767.0 if peak > 0 else 1.0
                data = np.rint(values / gain).astype("<i2").tobytes()
                db.execute("INSERT INTO emg VALUES (?, ?, ?, ?, ?, ?)",
                           (trial_id, muscle, rate, float(emg["time_s"].iloc[0]), gain, data))
            db.commit()
    db.execute("PRAGMA user_version=3")
    db.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    db.close()


def table_sizes(path: Path) -> dict[str, float]:
    """MB per table and index (SQLite's dbstat; empty if this SQLite lacks it)."""
    with sqlite3.connect(path) as db:
        try:
            rows = db.execute("SELECT name, SUM(pgsize) FROM dbstat GROUP BY name ORDER BY 2 DESC").fetchall()
        except sqlite3.Error:
            return {}
    return {str(name): size / 1e6 for name, size in rows if size >= 1e5}


def column_shares(path: Path) -> list[tuple[str, str, float, float]]:
    """Per sample column: its filters, stored MB and stored/decoded ratio, largest first."""
    stored: Counter[str] = Counter()
    raw: Counter[str] = Counter()
    kinds: dict[str, set[str]] = {}
    with sqlite3.connect(path) as db:
        for rows, blob in db.execute("SELECT row_count, data FROM sample_chunks"):
            for name, (kind, size) in column_sizes(blob).items():
                stored[name] += size
                raw[name] += rows * (8 if name in TRIAL_COLUMNS else 0)
                kinds.setdefault(name, set()).add(kind)
    return [(name, "+".join(sorted(kinds[name])), size / 1e6, size / max(raw[name], 1))
            for name, size in stored.most_common()]


def codec_speed(path: Path, table: str, *, grids: bool, limit: int = 400) -> tuple[float, float, float]:
    """Encode and decode time (ms per MB of decoded values) and the stored/decoded ratio, on up to
    ``limit`` chunks of ``table`` spread over the store."""
    with sqlite3.connect(path) as db:
        count = db.execute(f"SELECT COUNT(*) FROM {table}").fetchone()[0]
        step = max(1, count // limit)
        blobs = [b for (b,) in db.execute(f"SELECT data FROM {table} WHERE rowid % ? = 0", (step,))]
    encode_columns(decode_columns(blobs[0]))  # load the compiled predictor once (numba's disk cache)
    start = time.perf_counter()
    decoded = [decode_columns(blob) for blob in blobs]
    decode_s = time.perf_counter() - start
    start = time.perf_counter()
    encoded = [encode_columns(columns, grids=KNOWN_GRIDS if grids else None) for columns in decoded]
    encode_s = time.perf_counter() - start
    megabytes = sum(a.nbytes for columns in decoded for a in columns.values()) / 1e6
    ratio = sum(len(b) for b in encoded) / (megabytes * 1e6)
    return 1e3 * encode_s / megabytes, 1e3 * decode_s / megabytes, ratio


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--participants", type=int, default=17)
    parser.add_argument("--store", type=Path, help="measure this store instead of running a study")
    parser.add_argument("--legacy-copy", type=Path, help="keep the schema-3 copy here")
    parser.add_argument("--no-before", action="store_true", help="skip the schema-3 copy")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        store = args.store
        if store is None:
            from bowden.study.pipeline import StudySettings, run_study

            settings = StudySettings(participants=args.participants)
            store = run_study(settings, Path(tmp) / "study", force=True).store
        with sqlite3.connect(store) as db:
            db.execute("PRAGMA wal_checkpoint(TRUNCATE)")
            n_trials = db.execute("SELECT COUNT(*) FROM trials").fetchone()[0]
        after = store.stat().st_size / 1e6
        print(f"store ({n_trials} trials)        {after:7.1f} MB   ratio to the {TARGET_MB:.0f} MB target "
              f"{after / TARGET_MB:.2f}")
        for name, size in table_sizes(store).items():
            print(f"  {name:<28} {size:7.1f} MB")
        print("sample columns (filter, stored MB, ratio to float64)")
        for name, kinds, size, ratio in column_shares(store):
            print(f"  {name:<28} {kinds:<8} {size:7.1f} MB  {ratio:5.2f}")
        for table, grids in (("sample_chunks", True), ("emg_chunks", False)):
            encode_ms, decode_ms, ratio = codec_speed(store, table, grids=grids)
            print(f"codec on {table:<14} encode {encode_ms:6.1f} ms/MB, decode {decode_ms:6.1f} ms/MB, "
                  f"stored/decoded {ratio:.3f}")
        if not args.no_before:
            legacy = args.legacy_copy or Path(tmp) / "legacy.db"
            write_legacy_copy(store, legacy)
            before = legacy.stat().st_size / 1e6
            print(f"schema-3 layout (before)     {before:7.1f} MB   ratio to the target "
                  f"{before / TARGET_MB:.2f}; after/before {after / before:.2f}")
            for name, size in table_sizes(legacy).items():
                print(f"  {name:<28} {size:7.1f} MB")


if __name__ == "__main__":
    main()
