"""``bowden sweep`` end to end: a run on an existing scheduler, and every refusal (exit 1, no traceback)."""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest

from bowden.cli import main


def run_cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(["sweep", *argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_sweep_on_an_existing_scheduler(dask_client, capsys, tmp_path: Path):
    spec = tmp_path / "narrow.toml"
    spec.write_text(
        'name = "narrow"\nparticipants = 2\nrepetitions = 2\nsupport = [0.5]\nspeeds = ["V3"]\n'
        'bench = "quick"\n[axes]\nblend_velocity_01_rad_s = [-1.0, -0.1]\n'
    )
    out = tmp_path / "out"
    address = dask_client.scheduler.address
    code, stdout, stderr = run_cli(
        capsys, "--spec", str(spec), "--axis", "blend_velocity_99_rad_s=0.5", "--scheduler", address,
        "--out", str(out), "--quiet",
    )
    assert code == 0, stderr
    results = pd.read_parquet(out / "results.parquet")
    assert len(results) == 2 * 2 * 3  # points × participants × phases
    assert set(results["blend_velocity_99_rad_s"]) == {0.5}
    assert "lowest tension RMSE" in stdout and "smallest lowering peak" in stdout
    assert str((out / "results.parquet").resolve()) in stdout
    assert "4 computed, 0 already done" in stdout
    code, stdout, _ = run_cli(
        capsys, "--spec", str(spec), "--axis", "blend_velocity_99_rad_s=0.5", "--scheduler", address,
        "--out", str(out), "--quiet",
    )
    assert code == 0 and "0 computed, 4 already done" in stdout


def test_list_names_presets_and_axes(capsys):
    code, stdout, _ = run_cli(capsys, "--list")
    assert code == 0
    assert "blend-velocity   39 points × 17 participants" in stdout
    for name in ("blend_velocity_01_rad_s", "blend_width_rad_s", "sheath_kinetic_coefficient"):
        assert name in stdout


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        ((), "nothing to sweep"),
        (("fastest",), "unknown sweep preset 'fastest'"),
        (("--axis", "friction=0.1"), "unknown sweep axis 'friction'"),
        (("--axis", "blend_width_rad_s=-0.5"), "blend_width_rad_s = -0.5 must be positive"),
        (
            ("--axis", "blend_velocity_01_rad_s=1", "--axis", "blend_velocity_99_rad_s=0.5"),
            "no point of the sweep has blend_velocity_01_rad_s < blend_velocity_99_rad_s",
        ),
        (("--axis", "blend_velocity_99_rad_s"), "expected NAME=V1,V2"),
        (("--axis", "blend_velocity_99_rad_s=1,x"), "is not a comma-separated list of numbers"),
        (("blend-velocity", "--participants", "1"), "participants must be an integer in [2, 500]"),
        (("blend-velocity", "--seeds", "a"), "--seeds: 'a' is not a comma-separated list of integers"),
        (("blend-velocity", "--support", "0.75"), "support '0.75' is not a condition"),
        (("blend-velocity", "--speeds", "V9"), "speeds: unknown value 'V9'"),
        (("blend-velocity", "--spec", "x.toml"), "give a preset or --spec FILE, not both"),
        (("blend-velocity", "--scheduler", "tcp://127.0.0.1:9", "--workers", "2"), "--workers"),
        (("blend-velocity", "--top", "0"), "--top must be in [1, 1000]"),
    ],
)
def test_bad_requests_exit_1_with_one_line(capsys, argv, message):
    code, _, stderr = run_cli(capsys, *argv)
    assert code == 1
    assert stderr.startswith("bowden: error: ") and message in stderr
    assert "Traceback" not in stderr and stderr.count("\n") == 1


def test_bad_spec_file_exits_1(capsys, tmp_path: Path):
    spec = tmp_path / "bad.toml"
    spec.write_text("[axes]\nblend_velocity_99_rad_s = [0.5]\nspeed = 3\n")
    code, _, stderr = run_cli(capsys, "--spec", str(spec))
    assert code == 1 and "unknown sweep axis 'speed'" in stderr


def test_without_the_cluster_extra_the_error_names_it(capsys, monkeypatch, tmp_path: Path):
    # A None entry in sys.modules makes `import distributed` raise ImportError, as on an install
    # without the extra.
    monkeypatch.setitem(sys.modules, "distributed", None)
    code, _, stderr = run_cli(
        capsys, "--axis", "blend_velocity_99_rad_s=0.5", "--participants", "2", "--out", str(tmp_path / "o")
    )
    assert code == 1
    assert "pip install 'bowden[cluster]'" in stderr and stderr.count("\n") == 1
    assert not (tmp_path / "o").exists()  # refused before anything was written
