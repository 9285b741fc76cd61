"""benchmarks/compensation.py keeps what it computed: rows appended per suit, a suit `identify` refuses
named in one line and counted, never a traceback that loses the run (issue 28, structural-32-0)."""

from __future__ import annotations

import sys
from pathlib import Path
from types import ModuleType

import pandas as pd
import pytest
from tests.module_from_path import load_module

from bowden.errors import RecordingError
from bowden.sim.parameters import SuitParameters
from bowden.sim.plant_family import FamilyPlant

ROOT = Path(__file__).resolve().parents[2]
REFUSAL = ("bench recording <table>: 1 problem:\n  - column motor_torque_nm, row 213864: 50.0008 exceeds "
           "the plausible ±50 Nm")


def _benchmark() -> ModuleType:
    return load_module("compensation_benchmark", ROOT / "benchmarks" / "compensation.py")


def _rows(plant: str) -> pd.DataFrame:
    """One participant's trials on every (condition, speed) cell, the dynamic compensation 0.5× the
    paper's."""
    rows = []
    for condition in ("pretension", "support_25", "support_50"):
        for speed in ("V1", "V2", "V3"):
            for compensation, scale in (("paper", 1.0), ("dynamic", 0.5)):
                rows.append({"plant": plant, "participant": "P01", "condition": condition, "speed": speed,
                             "compensation": compensation, "recommended": "dynamic",
                             "recommended_why": "beats the paper's", "tension_rmse_n": 4.0 * scale,
                             "onset_peak_pct": 40.0 * scale, "onset_dip_pct": -10.0})
    return pd.DataFrame(rows)


def test_a_refused_suit_is_named_counted_and_the_others_saved(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    module = _benchmark()
    suit = SuitParameters()
    plants = [FamilyPlant(name, name, suit) for name in ("good", "refused", "crashes")]
    monkeypatch.setattr(module, "structural_plants", lambda: plants[:2])

    def compare(suits: list[FamilyPlant], settings: object, progress: object = None) -> pd.DataFrame:
        for plant in suits:
            if plant.name == "refused":
                raise RecordingError(REFUSAL)
            if plant.name == "crashes":
                raise RuntimeError("the machine went down")
        return pd.concat([_rows(plant.name) for plant in suits], ignore_index=True)

    monkeypatch.setattr(module, "compare_compensations", compare)
    saved = tmp_path / "rows.csv"
    argv = ["compensation.py", "--random", "0", "--seed", "1", "--save-rows", str(saved)]
    monkeypatch.setattr(sys, "argv", argv)
    module.main()
    out = capsys.readouterr().out
    refusal = [line for line in out.splitlines() if "refused NOT IDENTIFIED" in line]
    assert refusal == ["  refused NOT IDENTIFIED: RecordingError: bench recording <table>: 1 problem: - "
                       "column motor_torque_nm, row 213864: 50.0008 exceeds the plausible ±50 Nm"]
    assert "2 suits (1 identified)" in out
    summary = next(line for line in out.splitlines() if line.startswith("  seed 1:"))
    assert "0 of 9 cells > 5 % worse" in summary
    assert summary.endswith("; 1 suit(s) not identified: refused (RecordingError: bench recording <table>: "
                            "1 problem: - column motor_torque_nm, row 213864: 50.0008 exceeds the plausible "
                            "±50 Nm)")
    pd.testing.assert_frame_equal(pd.read_csv(saved), _rows("good"))

    # A crash that is not a refusal still ends the run, but what was done before it is on disk.
    monkeypatch.setattr(module, "structural_plants", lambda: [plants[0], plants[2]])
    saved.unlink()
    with pytest.raises(RuntimeError, match="went down"):
        module.main()
    pd.testing.assert_frame_equal(pd.read_csv(saved), _rows("good"))
