"""``bowden identify``: outputs that name an input or cannot be written are refused before the fit."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from bowden.cli import main

from .law_bench import law_bench_frame


@pytest.fixture
def bench(tmp_path: Path) -> Path:
    path = tmp_path / "bench.csv"
    law_bench_frame(noise_torque_nm=0.01).to_csv(path, index=False)
    return path


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def one_line_error(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    assert err.startswith("bowden: error: ") and err.count("\n") == 1 and "Traceback" not in err
    return err


@pytest.mark.parametrize("flag", ["-o", "--figure"])
def test_an_output_naming_a_bench_recording_is_refused(
    bench: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], flag: str
) -> None:
    second = tmp_path / "second.parquet"
    law_bench_frame(noise_torque_nm=0.01, seed=1).to_parquet(second)
    before = {path: digest(path) for path in (bench, second)}
    outputs = ["-o", str(tmp_path / "model.json"), flag, str(tmp_path / "." / second.name)]
    assert main(["identify", str(bench), str(second), *outputs]) == 1
    assert f"{flag} {tmp_path / '.' / second.name} is a bench recording" in one_line_error(capsys)
    assert {path: digest(path) for path in (bench, second)} == before
    assert not (tmp_path / "model.json").exists()


def test_figure_and_model_on_one_path_are_refused(
    bench: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = tmp_path / "model.json"
    assert main(["identify", str(bench), "-o", str(model), "--figure", str(model)]) == 1
    assert f"--figure {model} is the model file (-o)" in one_line_error(capsys)
    assert not model.exists()


@pytest.mark.parametrize(
    ("figure", "reason"),
    [
        ("missing/fig.png", "does not exist"),
        ("a_file/fig.png", "is not a directory"),
        (".", "it is a directory"),
        ("fig.xyz", "matplotlib does not write '.xyz' files"),
    ],
)
def test_a_bad_figure_path_leaves_no_model_behind(
    bench: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], figure: str, reason: str
) -> None:
    (tmp_path / "a_file").write_text("x")
    model = tmp_path / "model.json"
    assert main(["identify", str(bench), "-o", str(model), "--figure", str(tmp_path / figure)]) == 1
    err = one_line_error(capsys)
    assert f"cannot write the figure (--figure) to {tmp_path / figure}" in err and reason in err
    assert not model.exists()


def test_a_directory_as_model_path_is_refused(
    bench: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["identify", str(bench), "-o", str(tmp_path)]) == 1
    assert "cannot write the model (-o) to" in one_line_error(capsys)


def test_an_existing_file_that_is_not_a_model_is_not_replaced(
    bench: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Not an input of this run, but a recording all the same: the model file's own guard keeps it.
    other = tmp_path / "other_recording.csv"
    other.write_text("time_s,motor_torque_nm\n0.0,0.1\n")
    assert main(["identify", str(bench), "-o", str(other)]) == 1
    assert "not a bowden model file" in one_line_error(capsys)
    assert other.read_text() == "time_s,motor_torque_nm\n0.0,0.1\n"
