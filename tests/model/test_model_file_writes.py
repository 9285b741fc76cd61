"""How ``model.json`` is written: usual permissions, and never over a file that is not a model."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest

from bowden.errors import OutputFileError
from bowden.model import CompensationModel
from bowden.model.model_file import load_model, save_model

MODEL = CompensationModel.from_friction(k=0.1)


@pytest.fixture
def umask_022() -> Iterator[None]:
    previous = os.umask(0o022)
    try:
        yield
    finally:
        os.umask(previous)


def test_model_file_gets_the_usual_permissions(tmp_path: Path, umask_022: None) -> None:
    path = tmp_path / "model.json"
    save_model(MODEL, path)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644  # 0o666 less the umask, not mkstemp's 0o600
    os.umask(0o077)
    save_model(MODEL, path)  # replacing follows the umask too
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert load_model(path) == MODEL
    assert [p.name for p in tmp_path.iterdir()] == ["model.json"]  # no temporary file left


def test_an_older_model_file_is_replaced(tmp_path: Path) -> None:
    path = tmp_path / "model.json"
    save_model(CompensationModel.from_friction(k=0.2), path)
    save_model(MODEL, path)
    assert load_model(path) == MODEL


def test_a_file_that_is_not_a_model_is_never_replaced(tmp_path: Path) -> None:
    recording = tmp_path / "bench.csv"
    recording.write_text("time_s,motor_torque_nm\n0.0,0.1\n")
    with pytest.raises(OutputFileError, match=r"refusing to replace .*bench\.csv.*not a bowden model"):
        save_model(MODEL, recording)
    assert recording.read_text() == "time_s,motor_torque_nm\n0.0,0.1\n"


def test_an_empty_file_may_be_replaced(tmp_path: Path) -> None:
    path = tmp_path / "model.json"
    path.touch()
    save_model(MODEL, path)
    assert load_model(path) == MODEL


@pytest.mark.parametrize("where", ["directory", "missing folder", "under a file"])
def test_unwritable_paths_are_output_file_errors_naming_the_path(tmp_path: Path, where: str) -> None:
    (tmp_path / "a_file").write_text("x")
    target = {
        "directory": tmp_path,
        "missing folder": tmp_path / "missing" / "model.json",
        "under a file": tmp_path / "a_file" / "model.json",
    }[where]
    with pytest.raises(OutputFileError, match=f"cannot write the model to {target}"):
        save_model(MODEL, target)
