"""Summary warnings, the regression figure, and the ``bowden identify`` command end to end."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib.colors
import numpy as np
import pytest

from bowden.cli import main
from bowden.contracts import BENCH_ELEVATION
from bowden.errors import OutputFileError, ParameterError
from bowden.identify import (
    LOWERING,
    RAISING,
    SummaryThresholds,
    TransmissionIdentifier,
    identification_summary,
    plot_identification,
    robustfit,
    save_identification_figure,
)
from bowden.identify.figure import COLOURS
from bowden.model.model_file import load_model

from .law_bench import law_bench_frame


def line_fit(slope: float, intercept: float, n: int, noise: float, seed: int = 0):  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(seed)
    tension = rng.uniform(5.0, 60.0, n)
    return robustfit(tension, intercept + slope * tension + rng.normal(0.0, noise, n))


def test_summary_k_and_single_bend_check_by_hand() -> None:
    # Slopes 0.0427778 and 0.0286364 (k = 0.1, R = 35 mm): ratio ((1.1)/(0.9))² = 1.4938, gm = 35 mm.
    summary = identification_summary(
        line_fit(0.035 * 1.1 / 0.9, 0.05, 2000, 1e-4),
        line_fit(0.035 * 0.9 / 1.1, -0.02, 2000, 1e-4, seed=1),
        pulley_radius_m=0.035,
    )
    assert summary.k == pytest.approx(0.1, rel=1e-3)
    assert summary.geometric_mean_slope_m == pytest.approx(0.035, rel=1e-4)
    assert summary.consistent_with_one_k
    text = summary.format()
    assert "k = mu·sin(phi/2) = 0.100" in text
    assert "consistent with one k" in text and "R² fitlm-robust" in text and "R² OLS" in text


def test_summary_warns_about_little_data_poor_fit_and_outliers() -> None:
    sparse = line_fit(0.043, 0.05, 60, 0.002)
    poor = line_fit(0.0286, 0.0, 2000, 0.4, seed=2)
    summary = identification_summary(sparse, poor, pulley_radius_m=0.035)
    joined = "\n".join(summary.warnings)
    assert "raising: only 60 steady-state samples (< 500)" in joined
    assert "lowering: poor fit, R² = " in joined
    rng = np.random.default_rng(3)
    tension = rng.uniform(5.0, 60.0, 1000)
    torque = 0.0286 * tension + rng.normal(0.0, 0.005, 1000)
    torque[:200] += 1.0  # a second population: 20 % of the samples
    contaminated = robustfit(tension, torque)
    summary = identification_summary(line_fit(0.043, 0.05, 1000, 0.005), contaminated, pulley_radius_m=0.035)
    assert any("lowering: the robust fit rejected 20.0 %" in w for w in summary.warnings)
    with pytest.raises(ParameterError, match="min_r_squared"):
        SummaryThresholds(min_r_squared=2.0)


def test_figure_draws_both_directions_in_the_paper_colours(tmp_path: Path) -> None:
    identifier = TransmissionIdentifier().fit(law_bench_frame(noise_torque_nm=0.01))
    fits = {RAISING: identifier.raising_fit_, LOWERING: identifier.lowering_fit_}
    figure = plot_identification(identifier.selection_, fits, max_points_per_direction=500)
    axes = figure.axes[0]
    assert axes.get_xlabel().startswith("cable tension") and axes.get_ylabel().startswith("motor torque")
    lines = axes.get_lines()
    assert len(lines) == 2
    for line, direction in zip(lines, (RAISING, LOWERING), strict=True):
        assert matplotlib.colors.same_color(line.get_color(), COLOURS[direction])
        x, y = line.get_data()
        fit = fits[direction]
        np.testing.assert_allclose(y, fit.intercept + fit.slope * np.asarray(x))
        assert f"R² = {fit.r_squared_fitlm_robust:.4f}" in line.get_label()
    scatters = axes.collections
    assert [len(s.get_offsets()) for s in scatters] == [500, 500]
    path = save_identification_figure(identifier.selection_, fits, tmp_path / "fig.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(OutputFileError, match="cannot write the figure"):
        save_identification_figure(identifier.selection_, fits, tmp_path / "missing" / "fig.png")


def test_cli_writes_model_summary_and_figure(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bench = tmp_path / "bench.parquet"
    law_bench_frame(noise_tension_n=0.3, noise_torque_nm=0.01).to_parquet(bench)
    model_path = tmp_path / "model.json"
    figure_path = tmp_path / "fig.png"
    code = main(["identify", str(bench), "-o", str(model_path), "--figure", str(figure_path)])
    out = capsys.readouterr().out
    assert code == 0
    assert "raising" in out and "lowering" in out and "Implied friction: k = " in out
    model = load_model(model_path)
    assert model.raising.slope_m == pytest.approx(0.035 * 1.1 / 0.9, rel=0.01)
    assert json.loads(model_path.read_text())["provenance"]["source_files"] == [str(bench)]
    assert figure_path.stat().st_size > 10_000


def test_cli_thresholds_in_degrees(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bench = tmp_path / "bench.csv"
    law_bench_frame(noise_torque_nm=0.01).to_csv(bench, index=False)
    narrow = ["--min-elevation-deg", "40", "--max-elevation-deg", "60"]
    assert main(["identify", str(bench), "-o", str(tmp_path / "a.json")]) == 0
    assert main(["identify", str(bench), "-o", str(tmp_path / "b.json"), *narrow]) == 0
    wide, cut = (load_model(tmp_path / name) for name in ("a.json", "b.json"))
    assert wide.raising_fit is not None and cut.raising_fit is not None
    assert cut.raising_fit.n < 0.5 * wide.raising_fit.n


def test_cli_bad_recording_is_one_line_error_not_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    frame = law_bench_frame()
    frame[BENCH_ELEVATION] = np.degrees(frame[BENCH_ELEVATION])
    frame["extra"] = 1.0
    bench = tmp_path / "bench.csv"
    frame.to_csv(bench, index=False)
    code = main(["identify", str(bench), "-o", str(tmp_path / "model.json")])
    err = capsys.readouterr().err
    assert code == 1
    assert err.startswith("bowden: error: bench recording")
    assert "'extra' (column 7)" in err and "Traceback" not in err
    assert not (tmp_path / "model.json").exists()
    # With the extra column ignored, the next problem is reported: elevation in degrees.
    code = main(["identify", str(bench), "-o", str(tmp_path / "m.json"), "--ignore-extra-columns"])
    assert code == 1 and "looks like degrees" in capsys.readouterr().err


def test_cli_unwritable_model_path(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bench = tmp_path / "bench.csv"
    law_bench_frame(noise_torque_nm=0.01).to_csv(bench, index=False)
    code = main(["identify", str(bench), "-o", str(tmp_path / "no" / "such" / "model.json")])
    assert code == 1
    assert "cannot write the model" in capsys.readouterr().err
