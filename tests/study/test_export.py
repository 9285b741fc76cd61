"""The export of a study store: every table a researcher needs, the raw sEMG on request."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bowden.contracts import MUSCLES, TRIAL_COLUMNS
from bowden.errors import OutputFileError, StoreError
from bowden.runtime.recorder import TrialInfo
from bowden.store.export import export_paths
from bowden.store.study_store import StudyStore

TABLES = ("participants", "trials", "samples", "events", "questionnaires", "outcomes", "artifacts")


def samples(n: int = 100) -> pd.DataFrame:
    t = np.arange(n) * 0.002
    frame = pd.DataFrame({name: np.cos(t * (i + 1)) for i, name in enumerate(TRIAL_COLUMNS)})
    frame["time_s"], frame["controller_state"], frame["fault_flags"] = t, 1, 0
    return frame


def emg(muscles: tuple[str, ...], n: int, start_s: float, seed: int) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    values = {m: rng.normal(0.0, 1e-4, n) for m in muscles}
    return pd.DataFrame({"time_s": start_s + np.arange(n) / 2000.0, **values})


@pytest.fixture
def store(tmp_path: Path):  # type: ignore[no-untyped-def]
    with StudyStore(tmp_path / "study.db") as opened:
        first = opened.write_trial(
            TrialInfo(participant="P01", condition="no_suit", speed="V1"),
            samples(),
            emg=emg(MUSCLES, 300, 0.5, seed=1),
        )
        # A second trial recorded with two muscles only, and one without EMG.
        opened.write_trial(
            TrialInfo(participant="P02", condition="support_50", speed="V3", support=0.5),
            samples(),
            emg=emg(MUSCLES[:2], 200, 0.0, seed=2),
        )
        opened.write_trial(TrialInfo(participant="P02", condition="pretension", speed="V2"), samples())
        with opened._db:
            opened._db.execute(
                "INSERT INTO events (trial_id, time_s, kind, message) "
                "VALUES (?, 0.1, 'fault', 'overcurrent')",
                (first,),
            )
        opened.put_artifact("model.json", '{"format": "bowden.compensation_model"}')
        yield opened


@pytest.mark.parametrize("file_format", ["parquet", "csv"])
def test_every_table_is_exported_and_emg_only_on_request(store, tmp_path: Path, file_format: str) -> None:  # type: ignore[no-untyped-def]
    files = store.export(tmp_path / "out", file_format=file_format)
    assert [f.name for f in files] == [f"{name}.{file_format}" for name in TABLES]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(f.name for f in files)
    read = pd.read_parquet if file_format == "parquet" else pd.read_csv
    events = read(tmp_path / "out" / f"events.{file_format}")
    assert events.loc[0, ["participant", "condition", "speed", "kind", "message"]].tolist() == [
        "P01",
        "no_suit",
        "V1",
        "fault",
        "overcurrent",
    ]
    artifacts = read(tmp_path / "out" / f"artifacts.{file_format}")
    assert artifacts["name"].tolist() == ["model.json"]
    assert artifacts["content"].iloc[0] == '{"format": "bowden.compensation_model"}'


@pytest.mark.parametrize("file_format", ["parquet", "csv"])
def test_emg_rows_carry_their_trial_and_the_stored_values(store, tmp_path: Path, file_format: str) -> None:  # type: ignore[no-untyped-def]
    files = store.export(tmp_path / "out", file_format=file_format, include_emg=True)
    assert files[-1].name == f"emg.{file_format}"
    exported = pd.read_parquet(files[-1]) if file_format == "parquet" else pd.read_csv(files[-1])
    assert list(exported.columns) == ["trial_id", "participant", "condition", "speed", "time_s", *MUSCLES]
    assert exported.groupby("trial_id").size().to_dict() == {1: 300, 2: 200}  # trial 3 has no EMG
    for trial_id in (1, 2):
        rows = exported[exported["trial_id"] == trial_id].reset_index(drop=True)
        stored = store.trial_emg(trial_id)
        np.testing.assert_allclose(rows["time_s"], stored["time_s"], rtol=0, atol=1e-12)
        for muscle in MUSCLES:
            if muscle in stored:
                np.testing.assert_allclose(rows[muscle], stored[muscle], rtol=1e-12, atol=0)
            else:  # a muscle this trial did not record
                assert rows[muscle].isna().all()
    assert exported.loc[exported["trial_id"] == 2, "participant"].eq("P02").all()


def test_emg_export_of_a_store_without_emg_has_the_header_only(tmp_path: Path) -> None:
    with StudyStore(tmp_path / "study.db") as empty:
        [*_, path] = empty.export(tmp_path / "out", file_format="csv", include_emg=True)
    assert path.read_text().strip() == "trial_id,participant,condition,speed,time_s"


def test_unwritable_export_is_an_output_file_error(store, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    (tmp_path / "a_file").write_text("x")
    with pytest.raises(OutputFileError, match=f"cannot export the store to {tmp_path / 'a_file'}"):
        store.export(tmp_path / "a_file")


def test_paths_are_known_before_exporting_and_the_format_is_checked(tmp_path: Path) -> None:
    assert export_paths(tmp_path, file_format="csv", include_emg=True)[-1] == tmp_path / "emg.csv"
    with pytest.raises(StoreError, match="'parquet' or 'csv'"):
        export_paths(tmp_path, file_format="xlsx")
