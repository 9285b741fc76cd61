"""``bowden analyze``: output paths are checked before anything is analysed or written."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bowden.cli import main
from bowden.contracts import TRIAL_COLUMNS
from bowden.runtime.recorder import TrialInfo
from bowden.store.study_store import StudyStore


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def study(tmp_path: Path) -> Path:
    """A study directory: a store holding one short trial, and a bench recording beside it."""
    directory = tmp_path / "study"
    t = np.arange(200) * 0.002
    samples = pd.DataFrame({name: np.sin(t + i) for i, name in enumerate(TRIAL_COLUMNS)})
    samples["time_s"], samples["controller_state"], samples["fault_flags"] = t, 1, 0
    with StudyStore(directory / "study.db") as store:
        store.write_trial(TrialInfo(participant="P01", condition="no_suit", speed="V1"), samples)
    (directory / "bench.parquet").write_bytes(b"PAR1 stands in for a bench recording")
    return directory


def run_analyze(*arguments: str | Path) -> int:
    return main(["analyze", *map(str, arguments), "--quiet"])


def store_files(study: Path) -> dict[str, str]:
    return {path.name: digest(path) for path in sorted(study.iterdir())}


@pytest.mark.parametrize(
    ("flag", "target", "what"),
    [
        ("--report", "study.db", "the study store"),
        ("--report", "study.db-wal", "the study store's write-ahead log"),
        ("--report", "study.db-shm", "the study store's shared-memory index"),
        ("--report", "bench.parquet", "the bench recording"),
        ("--report", "../study/./study.db", "the study store"),
        ("--export", "study.db", "the study store"),
    ],
)
def test_an_output_naming_an_input_is_refused_and_nothing_changes(
    study: Path, capsys: pytest.CaptureFixture[str], flag: str, target: str, what: str
) -> None:
    before = store_files(study)
    assert run_analyze(study, flag, study / target) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"bowden: error: {flag} {study / target} is {what}")
    assert "Traceback" not in err and err.count("\n") == 1
    assert store_files(study) == before  # no report, no outcomes in the store


def test_a_symbolic_link_to_the_store_is_refused(study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    link = study.parent / "report.html"
    link.symlink_to(study / "study.db")
    before = store_files(study)
    assert run_analyze(study / "study.db", "--report", link) == 1
    assert "is the study store" in capsys.readouterr().err
    assert store_files(study) == before


def test_an_export_file_naming_an_input_is_refused(study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # --export DIR writes DIR/<table>.parquet: a bench recording named like a table is an input too.
    (study / "bench.parquet").rename(study / "samples.parquet")
    before = store_files(study)
    code = run_analyze(study, "--bench", study / "samples.parquet", "--export", study)
    assert code == 1
    assert f"--export {study / 'samples.parquet'} is the bench recording" in capsys.readouterr().err
    assert store_files(study) == before


@pytest.mark.parametrize(
    ("flag", "target", "reason"),
    [
        ("--report", ".", "it is a directory"),
        ("--report", "a_file/report.html", "a_file is not a directory"),
        ("--export", "a_file", "it exists and is not a directory"),
        ("--export", "a_file/export", "a_file is not a directory"),
    ],
)
def test_an_unwritable_output_is_one_line_naming_path_and_reason_before_any_work(
    study: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], flag: str, target: str, reason: str
) -> None:
    (tmp_path / "a_file").write_text("x")
    before = store_files(study)
    path = tmp_path / target
    assert run_analyze(study, "--report", tmp_path / "report.html", flag, path) == 1
    err = capsys.readouterr().err
    what = {"--report": "the report (--report)", "--export": "the export (--export)"}[flag]
    assert err.startswith(f"bowden: error: cannot write {what} to {path}: ") and reason in err
    assert "Traceback" not in err and err.count("\n") == 1
    assert not (tmp_path / "report.html").exists()  # the report is not written when the export cannot be
    assert store_files(study) == before


def test_a_read_only_folder_is_refused(
    study: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # /proc refuses new files whoever asks (root included), whatever its permission bits say.
    if not Path("/proc/self").is_dir():
        pytest.skip("needs Linux /proc")
    assert run_analyze(study, "--report", "/proc/report.html") == 1
    assert (
        "cannot write the report (--report) to /proc/report.html: /proc takes no new files"
        in capsys.readouterr().err
    )


def test_a_report_path_holding_another_file_is_refused_before_the_analysis(
    study: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    notes = tmp_path / "notes.txt"
    notes.write_text("the participant's remarks")
    before = store_files(study)
    assert run_analyze(study, "--report", notes) == 1
    assert f"refusing to replace {notes} by the report: it is not an HTML file" in capsys.readouterr().err
    assert notes.read_text() == "the participant's remarks"
    assert store_files(study) == before  # not analysed: no outcomes written into the store


def test_export_emg_needs_export(study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run_analyze(study, "--export-emg") == 1
    assert "--export-emg needs --export DIR" in capsys.readouterr().err


def test_help_says_what_the_export_holds(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["analyze", "--help"])
    text = "".join(capsys.readouterr().out.split())  # argparse wraps lines (also after hyphens)
    assert "participants,trials,samples,events,questionnaires,outcomes,artifacts" in text
    assert "(therawsEMGonlywith--export-emg)" in text
