"""A trial's encoding is decoded and compared before its frames are let go (issue 27, item 8)."""

from __future__ import annotations

import sqlite3
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from bowden.contracts import TRIAL_COLUMNS
from bowden.errors import StoreError
from bowden.runtime import TrialInfo
from bowden.store import sample_chunks
from bowden.store.column_codec import decode_columns
from bowden.store.study_store import StudyStore
from bowden.store.trial_encoding import encode_trial

INFO = TrialInfo(participant="P01", condition="support_50", speed="V2", support=0.5)


def samples(n: int, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    frame = pd.DataFrame({name: rng.normal(size=n) for name in TRIAL_COLUMNS})
    frame["time_s"] = np.arange(n) * 0.002
    frame["controller_state"] = rng.integers(1, 4, n)
    frame["fault_flags"] = rng.integers(0, 2**40, n)
    frame.loc[::7, "tension_n"] = np.nan
    return frame


def inject_codec_fault(monkeypatch: pytest.MonkeyPatch, faulty: Callable[[bool], bool]) -> None:
    """The sample encoder writes one value wrong (+1 N of desired tension) where ``faulty(compress)``."""
    encode = sample_chunks.encode_columns

    def encode_wrongly(columns: Mapping[str, Any], *, compress: bool = True, grids: Any = None) -> bytes:
        if faulty(compress):
            columns = dict(columns)
            wrong = np.array(columns["desired_tension_n"], dtype=np.float64)
            wrong[len(wrong) // 2] += 1.0
            columns["desired_tension_n"] = wrong
        return encode(columns, compress=compress, grids=grids)

    monkeypatch.setattr(sample_chunks, "encode_columns", encode_wrongly)


def decoded(chunks: list[sample_chunks.EncodedChunk]) -> pd.DataFrame:
    return pd.concat([pd.DataFrame(decode_columns(blob)) for *_head, blob in chunks], ignore_index=True)


def test_a_faulty_compressed_encoding_falls_back_to_a_faithful_one(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    frame = samples(sample_chunks.CHUNK_ROWS + 500)
    inject_codec_fault(monkeypatch, lambda compress: compress)
    trial = encode_trial(frame)
    pd.testing.assert_frame_equal(decoded(trial.samples), frame.loc[:, list(TRIAL_COLUMNS)], check_exact=True)
    assert "does not decode to its rows: column 'desired_tension_n' differs" in caplog.text


def test_a_trial_no_encoding_gives_back_is_refused_and_nothing_is_stored(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    inject_codec_fault(monkeypatch, lambda _compress: True)
    with StudyStore(tmp_path / "study.db") as store, pytest.raises(StoreError, match="does not decode"):
        store.write_trial(INFO, samples(300))
    with sqlite3.connect(tmp_path / "study.db") as connection:
        assert connection.execute("SELECT COUNT(*) FROM trials").fetchone()[0] == 0
        assert sample_chunks.sample_count(connection) == 0
