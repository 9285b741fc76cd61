"""``--motor``: the TDU's AK model on both backends, and the model file's motor (issue 31, item 1)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bowden.cli import build_parser, main
from bowden.cli._suit import CanSuitOptions, check_model_motor, motor_config
from bowden.errors import ModelFileError, ParameterError
from bowden.model import CompensationModel
from bowden.model.model_file import load_model, recorded_motor, save_model


def saved(tmp_path: Path, motor: str | None, name: str = "model.json") -> Path:
    path = tmp_path / name
    save_model(CompensationModel.from_friction(k=0.12), path, motor=motor)
    return path


def test_the_model_file_records_its_motor_and_still_loads(tmp_path: Path) -> None:
    path = saved(tmp_path, "AK70-10")
    assert json.loads(path.read_text())["motor"] == "AK70-10"
    assert recorded_motor(path) == "AK70-10"
    assert load_model(path).pulley_radius_m == CompensationModel.from_friction(k=0.12).pulley_radius_m
    assert recorded_motor(saved(tmp_path, None, "old.json")) is None  # files from before say nothing


def test_a_malformed_motor_field_is_named(tmp_path: Path) -> None:
    path = saved(tmp_path, "AK60-6")
    data = json.loads(path.read_text())
    data["motor"] = 7
    path.write_text(json.dumps(data))
    with pytest.raises(ModelFileError, match="'motor' must be a motor model name"):
        recorded_motor(path)


def test_a_model_from_another_motor_is_refused_unless_allowed(tmp_path: Path) -> None:
    path = saved(tmp_path, "AK60-6")
    with pytest.raises(ParameterError, match=r"identified on an AK60-6, not the --motor AK70-10: .*"
                                             r"--allow-other-motor"):
        check_model_motor(path, "AK70-10")
    assert "--allow-other-motor" in (check_model_motor(path, "AK70-10", allow_other=True) or "")
    assert check_model_motor(path, "AK60-6") is None
    assert "does not record" in (check_model_motor(saved(tmp_path, None, "old.json"), "AK60-6") or "")


def test_motor_option_sets_the_drivers_ranges_and_clamp() -> None:
    args = build_parser().parse_args(["run", "--backend", "can", "--motor", "AK70-10"])
    options = CanSuitOptions.from_args(args)
    config = motor_config(options)
    limits = config.limits
    assert (limits.velocity_rad_s, limits.torque_nm, config.torque_limit_nm) == (50.0, 25.0, 25.0)
    paper = motor_config(CanSuitOptions())
    assert (paper.limits.torque_nm, paper.torque_limit_nm) == (15.0, 9.0)  # the AK60-6 keeps its 9 Nm peak


def test_a_firmware_variant_of_another_model_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", "--backend", "sim", "--motor", "AK70-10", "--firmware", "peak-9nm",
                 "--duration", "1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1
    assert "--firmware peak-9nm is not a firmware variant of the AK70-10 (--motor)" in err[0]


def test_run_refuses_the_model_of_another_motor_before_any_device(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    path = saved(tmp_path, "AK60-6")
    code = main(["run", "--backend", "sim", "--motor", "AK70-10", "--model", str(path), "--duration", "1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1, err
    assert "not the --motor AK70-10" in err[0] and "simulated suit" not in err[0]
