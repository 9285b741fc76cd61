"""The suit options and openers shared by ``bowden run`` and ``bowden serve`` (``bowden.cli._suit``)."""

from __future__ import annotations

import argparse
import math
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from bowden.cli import build_parser, main
from bowden.cli._run_plan import run_reference
from bowden.cli._suit import CanSuitOptions
from bowden.cli.serve import serve_config
from bowden.errors import ParameterError
from bowden.model import CompensationModel
from bowden.model.model_file import save_model
from bowden.sim.parameters import SuitParameters
from bowden.store.sample_chunks import read_samples

HARDWARE = ["--channel", "can1", "--interface", "virtual", "--motor-id", "3", "--firmware", "peak-9nm",
            "--direction", "-1", "--imu-port", "9001", "--calibration-s", "0.5", "--i2c-bus", "2",
            "--load-cell-gain", "250"]


@pytest.fixture
def model(tmp_path: Path) -> Path:
    path = tmp_path / "model.json"
    save_model(CompensationModel.from_friction(k=0.12), path)
    return path


def test_run_and_serve_read_the_same_real_suit_options() -> None:
    parser = build_parser()
    from_run = CanSuitOptions.from_args(parser.parse_args(["run", "--backend", "can", *HARDWARE]))
    from_serve = CanSuitOptions.from_args(parser.parse_args(["serve", "--backend", "can", *HARDWARE]))
    expected = CanSuitOptions(channel="can1", interface="virtual", motor_id=3, firmware="peak-9nm",
                              direction=-1, imu_port=9001, calibration_s=0.5, i2c_bus=2,
                              load_cell_gain_n_per_v=250.0)
    assert from_run == from_serve == expected
    defaults = CanSuitOptions.from_args(parser.parse_args(["serve"]))
    assert defaults == CanSuitOptions()  # argparse defaults are the dataclass's
    assert (defaults.channel, defaults.interface, defaults.imu_port) == ("can0", "socketcan", 8000)


@pytest.mark.parametrize(("option", "value", "field"), [
    ("--motor-id", "0", "motor_id"),
    ("--motor-id", "2048", "motor_id"),
    ("--imu-port", "0", "imu_port"),
    ("--calibration-s", "0", "calibration_s"),
    ("--calibration-s", "nan", "calibration_s"),
    ("--load-cell-gain", "0", "load_cell_gain_n_per_v"),
    ("--i2c-bus", "-1", "i2c_bus"),
    ("--channel", "", "channel"),
])
def test_bad_suit_options_are_refused_by_both_commands_before_any_device(
    option: str, value: str, field: str, model: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # The interface would fail to open; the option is refused first, naming the flag (never the
    # dataclass field behind it).
    common = ["--backend", "can", "--model", str(model), "--interface", "no-such-interface", option, value]
    assert main(["run", *common, "--duration", "1"]) == 1
    err = capsys.readouterr().err
    assert f"{option} " in err and "CanSuitOptions" not in err and f".{field}" not in err
    args = build_parser().parse_args(["serve", *common, "--store", str(tmp_path / "s.sqlite")])
    with pytest.raises(ParameterError, match=f"^{option} ") as refused:
        serve_config(args)
    assert "CanSuitOptions" not in str(refused.value)
    assert not (tmp_path / "s.sqlite").exists()


def test_a_can_interface_that_cannot_be_opened_is_a_clear_error(
    model: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["run", "--backend", "can", "--model", str(model), "--interface", "no-such-interface",
                 "--channel", "can7", "--duration", "1"])
    assert code == 1
    assert "cannot open the CAN interface no-such-interface:can7" in capsys.readouterr().err


def test_serve_can_needs_a_model_and_run_serve_needs_a_store(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["serve", "--backend", "can", "--store", str(tmp_path / "s.sqlite")]) == 1
    assert "--backend can needs --model" in capsys.readouterr().err
    assert main(["run", "--backend", "sim", "--serve"]) == 1
    assert "--serve needs --record" in capsys.readouterr().err
    assert main(["run", "--backend", "sim", "--participant", "Anna"]) == 1
    assert "not a pseudonymous id" in capsys.readouterr().err


@pytest.mark.parametrize(("speed", "duration_s", "lead_in_s", "repetitions"), [
    # Periods 2·1.875·80°/peak: V1 60 °/s → 5 s, V2 120 °/s → 2.5 s, V3 180 °/s → 5/3 s.
    ("V1", 30.0, 2.0, 5),  # 28 s hold 5 whole cycles
    ("V1", 27.0, 2.0, 5),  # exactly 5
    ("V2", 30.0, 0.0, 12),
    ("V3", 30.0, 2.0, 16),  # 28 / (5/3) = 16.8
    ("V1", 3.0, 2.0, 1),  # shorter than one cycle: one, cut by the duration
])
def test_the_run_reference_holds_the_whole_cycles_that_fit(
    speed: str, duration_s: float, lead_in_s: float, repetitions: int
) -> None:
    reference = run_reference(argparse.Namespace(speed=speed, duration=duration_s, lead_in=lead_in_s))
    assert reference.repetitions == repetitions and reference.start_s == lead_in_s
    assert math.degrees(reference.cycle.low_rad) == pytest.approx(20.0)
    assert math.degrees(reference.cycle.high_rad) == pytest.approx(100.0)
    if repetitions > 1:
        assert reference.end_s <= duration_s + 1e-9


def test_the_lead_in_is_checked() -> None:
    with pytest.raises(ParameterError, match="--lead-in"):
        run_reference(argparse.Namespace(speed="V1", duration=30.0, lead_in=-1.0))


def test_the_simulated_arm_follows_the_run_reference_from_the_loop_start(tmp_path: Path) -> None:
    store = tmp_path / "study.db"
    lead_in_s = 0.4
    assert main(["run", "--backend", "sim", "--duration", "2.6", "--lead-in", str(lead_in_s), "--speed", "V3",
                 "--rate", "250", "--record", str(store)]) == 0
    with sqlite3.connect(store) as connection:
        columns = ["time_s", "reference_elevation_rad", "elevation_rad"]
        rows = read_samples(connection).loc[:, columns].to_numpy()
    t, reference, elevation = rows.T
    reference_deg, elevation_deg = np.degrees(reference), np.degrees(elevation)
    # The recorded reference is the one shown: rest at 20°, one V3 cycle to 100° and back, rest.
    end_s = lead_in_s + 5.0 / 3.0
    assert reference_deg.max() == pytest.approx(100.0, abs=0.5)
    assert np.allclose(reference_deg[(t < lead_in_s) | (t > end_s)], 20.0)
    # The simulated IMU reports the arm ``latency_s`` late; shifted by it, the arm is the reference
    # (to the IMU's noise and bias), resting during the lead-in and moving when it says.
    latency_s = SuitParameters().imu.latency_s
    settled = t > latency_s + 0.05
    followed = np.interp(t - latency_s, t, reference_deg)
    error_deg = np.abs(elevation_deg - followed)[settled]
    assert error_deg.mean() < 1.5 and error_deg.max() < 6.0
    assert np.all(np.abs(elevation_deg[settled & (t < lead_in_s)] - 20.0) < 3.0)


def test_serve_without_a_model_uses_the_simulated_suits_friction(tmp_path: Path) -> None:
    store = str(tmp_path / "s.sqlite")
    default = serve_config(build_parser().parse_args(["serve", "--store", store]))
    expected = CompensationModel.from_friction(k=SuitParameters().sheath.kinetic_coefficient)
    assert default.model.raising.slope_m == pytest.approx(expected.raising.slope_m, rel=1e-12)
    assert default.model.lowering.slope_m == pytest.approx(expected.lowering.slope_m, rel=1e-12)
    chosen = serve_config(build_parser().parse_args(["serve", "--store", store, "--friction-k", "0.2"]))
    assert chosen.model.raising.slope_m == pytest.approx(
        CompensationModel.from_friction(k=0.2).raising.slope_m, rel=1e-12
    )
