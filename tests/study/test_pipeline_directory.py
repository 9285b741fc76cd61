"""``bowden study --out DIR``: a directory it cannot vouch for is refused before anything is written.

All of these fail before the bench stage, so they take milliseconds.
"""

from __future__ import annotations

import hashlib
import json
import sqlite3
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bowden.cli import main
from bowden.contracts import BACKEND_CAN, BACKEND_SIM, TRIAL_COLUMNS
from bowden.errors import OutputFileError, StoreError
from bowden.model import CompensationModel
from bowden.model.model_file import save_model
from bowden.runtime.recorder import TrialInfo
from bowden.store.ownership import (
    FILES_MANIFEST,
    RECORDED_BY_KEY,
    STUDY_PIPELINE,
    files_not_written_by_study,
    made_by_study_pipeline,
    note_written,
    read_trial_origins,
)
from bowden.store.sample_chunks import sample_count
from bowden.store.study_store import StudyStore
from bowden.study import pipeline
from bowden.study.pipeline import StudySettings, run_study

SETTINGS = StudySettings(participants=2, repetitions=1, quick_bench=True, seed=4)
PIPELINE = {"backend": BACKEND_SIM, RECORDED_BY_KEY: STUDY_PIPELINE}
LIVE_SIM = {"backend": BACKEND_SIM, "rate_hz": 500.0}  # what `bowden run --backend sim --record` writes


def samples(n: int = 50) -> pd.DataFrame:
    t = np.arange(n) * 0.002
    frame = pd.DataFrame({name: np.sin(t + i) for i, name in enumerate(TRIAL_COLUMNS)})
    frame["time_s"], frame["controller_state"], frame["fault_flags"] = t, 1, 0
    return frame


def add_trial(store: StudyStore, metadata: dict[str, object], *, finished: bool = True) -> int:
    info = TrialInfo(participant="P01", condition="support_50", speed="V3", support=0.5, metadata=metadata)
    trial_id = store.write_trial(info, samples())
    if not finished:  # as a `kill -9` mid-trial leaves it: samples committed, no end time
        with store._db:
            store._db.execute("UPDATE trials SET ended_utc = NULL WHERE id = ?", (trial_id,))
    return trial_id


def snapshot(directory: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(directory.iterdir())}


def test_a_live_recording_store_without_settings_is_refused_untouched(tmp_path: Path) -> None:
    out = tmp_path / "kd"
    with StudyStore(out / "study.db") as store:
        add_trial(store, LIVE_SIM)
        add_trial(store, LIVE_SIM, finished=False)
    before = snapshot(out)
    with pytest.raises(StoreError, match=r"holds 2 trial\(s\) that bowden study did not record") as error:
        run_study(SETTINGS, out)
    assert "trial 2 of P01, backend 'sim', unfinished" in str(error.value)
    assert snapshot(out) == before  # no settings.json, no bench, the killed trial kept


def test_force_does_not_delete_somebody_elses_recordings(tmp_path: Path) -> None:
    out = tmp_path / "real"
    with StudyStore(out / "study.db") as store:
        add_trial(store, {"backend": BACKEND_CAN})
    (out / "settings.json").write_text(json.dumps(asdict(SETTINGS)))  # even beside matching settings
    before = snapshot(out)
    with pytest.raises(StoreError, match="never deletes or adds to another recording's store"):
        run_study(SETTINGS, out, force=True)
    assert snapshot(out) == before


def test_pipeline_trials_without_settings_json_are_refused(tmp_path: Path) -> None:
    out = tmp_path / "lost"
    with StudyStore(out / "study.db") as store:
        add_trial(store, PIPELINE)
    with pytest.raises(StoreError, match=r"holds study\.db with 1 trial\(s\) but no settings\.json"):
        run_study(SETTINGS, out)
    assert not (out / "settings.json").exists()


def test_a_bench_or_model_without_settings_json_is_not_taken_for_the_simulation(tmp_path: Path) -> None:
    (tmp_path / "model.json").write_text("{}")
    with pytest.raises(StoreError, match=r"holds model\.json but no settings\.json"):
        run_study(SETTINGS, tmp_path)


def test_a_file_that_is_not_a_study_store_is_refused(tmp_path: Path) -> None:
    with sqlite3.connect(tmp_path / "study.db") as db:
        db.execute("CREATE TABLE foo (x INTEGER)")
    before = snapshot(tmp_path)
    with pytest.raises(StoreError, match="is not a bowden study store"):
        run_study(SETTINGS, tmp_path, force=True)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(
    ("content", "problem"),
    [("{bad", r"not JSON: line 1, column 2"), ("[1, 2]", "a JSON list, not the settings object")],
)
def test_a_damaged_settings_file_is_a_clear_error(tmp_path: Path, content: str, problem: str) -> None:
    (tmp_path / "settings.json").write_text(content)
    with pytest.raises(StoreError, match=rf"settings\.json is damaged \({problem}"):
        run_study(SETTINGS, tmp_path)


def test_damaged_settings_on_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "settings.json").write_text("{bad")
    assert main(["study", "--participants", "2", "--quiet", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"bowden: error: {tmp_path / 'settings.json'} is damaged")
    assert err.count("\n") == 1 and "Traceback" not in err


@pytest.mark.parametrize("where", ["file", "under a file", "proc"])
def test_an_unusable_out_path_is_one_line_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], where: str
) -> None:
    (tmp_path / "some_file.csv").write_text("x")
    out = {
        "file": tmp_path / "some_file.csv",
        "under a file": tmp_path / "some_file.csv" / "study",
        "proc": Path("/proc/bowden-study"),  # refuses new entries, whoever asks
    }[where]
    assert main(["study", "--participants", "2", "--quiet", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("bowden: error: ") and str(out) in err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert (tmp_path / "some_file.csv").read_text() == "x"


def test_force_never_replaces_a_labs_own_model(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 27: `bowden study --out DIR --force` deleted the lab's model.json in DIR."""
    save_model(CompensationModel.from_friction(k=0.2), tmp_path / "model.json")  # the lab's identified model
    (tmp_path / "report.html").write_text("<p>the lab's own report</p>")
    before = snapshot(tmp_path)
    argv = ["study", "--participants", "2", "--quick-bench", "--quiet", "--force", "--out", str(tmp_path)]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "model.json (not written by bowden study), report.html (not written by bowden study)" in err
    assert "even with --force" in err and err.count("\n") == 1 and "Traceback" not in err
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("force", [True, False])
def test_a_model_changed_since_the_study_wrote_it_is_neither_replaced_nor_reused(
    tmp_path: Path, force: bool
) -> None:
    (tmp_path / "settings.json").write_text(json.dumps(asdict(SETTINGS)))
    save_model(CompensationModel.from_friction(k=0.1), tmp_path / "model.json")
    note_written(tmp_path, ["model.json"])
    save_model(CompensationModel.from_friction(k=0.3), tmp_path / "model.json")  # the lab put theirs there
    before = snapshot(tmp_path)
    with pytest.raises(StoreError, match=r"model\.json \(changed since bowden study wrote it\)"):
        run_study(SETTINGS, tmp_path, force=force)
    assert snapshot(tmp_path) == before


class _Stop(Exception):
    pass


def test_force_replaces_what_the_study_wrote(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "settings.json").write_text(json.dumps({**asdict(SETTINGS), "seed": 99}))
    save_model(CompensationModel.from_friction(k=0.1), tmp_path / "model.json")
    (tmp_path / "report.html").write_text("<p>the study's report</p>")
    note_written(tmp_path, ["model.json", "report.html"])

    def stop(*_args: object) -> None:
        raise _Stop  # after the old results are gone, before the new bench

    monkeypatch.setattr(pipeline, "_bench_stage", stop)
    with pytest.raises(_Stop):
        run_study(SETTINGS, tmp_path, force=True, workers=1)
    assert not (tmp_path / "model.json").exists() and not (tmp_path / "report.html").exists()
    assert json.loads((tmp_path / "settings.json").read_text()) == asdict(SETTINGS)
    assert files_not_written_by_study(tmp_path, ["model.json", "report.html"]) == []


def test_a_study_directory_from_before_the_list_of_files_stays_the_studys(tmp_path: Path) -> None:
    """Written before bowden study listed its files: its settings.json vouches for them, and the first
    run lists them."""
    (tmp_path / "settings.json").write_text(json.dumps(asdict(SETTINGS)))
    save_model(CompensationModel.from_friction(k=0.1), tmp_path / "model.json")
    assert files_not_written_by_study(tmp_path, ["model.json", "bench.parquet"]) == []
    note_written(tmp_path, ["model.json", "bench.parquet"])
    manifest = json.loads((tmp_path / FILES_MANIFEST).read_text())
    model_sha256 = hashlib.sha256((tmp_path / "model.json").read_bytes()).hexdigest()
    assert manifest == {"files": {"model.json": model_sha256}}


def test_out_being_a_file_is_an_output_file_error(tmp_path: Path) -> None:
    (tmp_path / "f").write_text("x")
    with pytest.raises(OutputFileError, match="is a file, not a directory"):
        run_study(SETTINGS, tmp_path / "f")


def test_only_the_pipelines_unfinished_trials_are_discarded(tmp_path: Path) -> None:
    with StudyStore(tmp_path / "study.db") as store:
        kept = [
            add_trial(store, LIVE_SIM, finished=False),
            add_trial(store, {"backend": BACKEND_CAN}, finished=False),
            add_trial(store, {}, finished=False),
            add_trial(store, PIPELINE),
        ]
        dropped = [
            add_trial(store, PIPELINE, finished=False),
            add_trial(store, {"backend": "simulation"}, finished=False),
        ]
        assert store.discard_unfinished_trials() == 2
        remaining = [row[0] for row in store._db.execute("SELECT id FROM trials ORDER BY id")]
        assert remaining == kept
        counts = {trial_id: sample_count(store._db, trial_id) for trial_id in store.trials_with_samples()}
    assert all(counts[trial_id] == 50 for trial_id in kept) and not set(dropped) & set(counts)


@pytest.mark.parametrize(
    ("metadata", "pipeline"),
    [
        (PIPELINE, True),
        ({"backend": "simulation"}, True),  # stores of bowden study before the mark
        (LIVE_SIM, False),
        ({"backend": BACKEND_CAN, RECORDED_BY_KEY: STUDY_PIPELINE}, False),  # never on the real suit
        ({"backend": "simulation", RECORDED_BY_KEY: "bowden serve"}, False),
        ({}, False),
    ],
)
def test_made_by_study_pipeline(metadata: dict[str, object], pipeline: bool) -> None:
    assert made_by_study_pipeline(metadata) is pipeline


def test_trial_origins_read_without_changing_the_file(tmp_path: Path) -> None:
    path = tmp_path / "study.db"
    assert read_trial_origins(path).n_trials == 0 and not path.exists()
    with StudyStore(path) as store:
        add_trial(store, PIPELINE)
        add_trial(store, LIVE_SIM)
    before = snapshot(tmp_path)
    origins = read_trial_origins(path)
    assert origins.n_trials == 2 and origins.foreign == ("trial 2 of P01, backend 'sim', finished",)
    assert snapshot(tmp_path) == before
