"""Identification of the dynamic compensation: a known law is recovered, bad data is refused by name."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bowden import contracts as c
from bowden.cli import main
from bowden.errors import FitError
from bowden.identify import TransmissionIdentifier
from bowden.identify.dynamic import identify_dynamic
from bowden.model.model_file import load_model

# The law the synthetic bench obeys (hand-chosen): Coulomb lines, drag, inertia.
RAISING = (0.08, 0.043)  # intercept Nm, slope m
LOWERING = (-0.07, 0.029)
DRAG = 0.04  # Nm·s/rad
INERTIA = 1.5e-3  # kg·m²
RATE = 200.0


def synthetic_bench(seed: int = 0, speeds: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0, 6.0)) -> pd.DataFrame:
    """Strokes up and down at several spool speeds and loads, torque from the law above plus noise
    and 2 % gross outliers; trapezoidal speed profiles (30 rad/s²) so that the ramps carry inertia."""
    rng = np.random.default_rng(seed)
    parts = []
    trial = 0
    t0 = 0.0
    for load in (10.0, 30.0, 60.0):
        for speed in speeds:
            for direction in (1.0, -1.0):
                travel = 3.0  # rad of spool
                ramp = speed / 30.0
                duration = travel / speed + ramp
                t = np.arange(0.0, duration + 0.3, 1.0 / RATE)
                velocity = direction * speed * np.clip(np.minimum(t / ramp, (duration - t) / ramp), 0.0, 1.0)
                acceleration = np.gradient(velocity, t)
                tension = load + 3.0 * np.sin(0.7 * t) + rng.normal(0, 0.3, t.size)
                up = RAISING[0] + RAISING[1] * tension
                down = LOWERING[0] + LOWERING[1] * tension
                torque = (up if direction > 0 else down) + DRAG * velocity + INERTIA * acceleration
                torque += rng.normal(0, 0.01, t.size)
                outliers = rng.random(t.size) < 0.02
                torque[outliers] += rng.normal(0, 0.5, int(outliers.sum()))
                spool = np.cumsum(velocity) / RATE
                elevation = math.radians(55.0) + 0.25 * direction * (spool - spool[-1] / 2) * direction
                parts.append(pd.DataFrame({
                    c.BENCH_TIME: t0 + t, c.BENCH_MOTOR_TORQUE: torque, c.BENCH_MOTOR_VELOCITY: velocity,
                    c.BENCH_TENSION: tension, c.BENCH_ELEVATION: elevation, c.BENCH_TRIAL: trial,
                }))
                trial += 1
                t0 += t[-1] + 1.0
    return pd.concat(parts, ignore_index=True)


def test_a_known_law_is_recovered() -> None:
    identifier = TransmissionIdentifier().fit(synthetic_bench())
    dynamic = identifier.model_.dynamic
    assert dynamic is not None
    assert dynamic.raising.intercept_nm == pytest.approx(RAISING[0], abs=0.005)
    assert dynamic.raising.slope_m == pytest.approx(RAISING[1], rel=0.01)
    assert dynamic.lowering.intercept_nm == pytest.approx(LOWERING[0], abs=0.005)
    assert dynamic.lowering.slope_m == pytest.approx(LOWERING[1], rel=0.01)
    assert dynamic.viscous_nm_s_rad == pytest.approx(DRAG, rel=0.05)
    assert dynamic.inertia_kg_m2 == pytest.approx(INERTIA, rel=0.05)
    fit = dynamic.fit
    assert fit is not None and fit.viscous_se_nm_s_rad < 0.1 * DRAG
    # The paper's per-direction lines absorb the drag in their intercepts: worse residual at steady state.
    dynamic_rms, paper_rms = dict(fit.regime_rms_nm), dict(fit.paper_rms_nm)
    assert dynamic_rms["steady raising"] < 0.5 * paper_rms["steady raising"]
    assert dynamic_rms["ramps"] < paper_rms["ramps"]


def test_one_speed_cannot_tell_drag_from_friction() -> None:
    identifier = TransmissionIdentifier().fit(synthetic_bench(speeds=(2.0,)))
    assert identifier.model_.dynamic is None
    assert identifier.dynamic_error_ is not None and "several spool speeds" in identifier.dynamic_error_
    with pytest.raises(FitError, match="several spool speeds"):
        identify_dynamic(identifier.selection_, identifier.model_)


def test_negative_drag_is_refused_by_name() -> None:
    frame = synthetic_bench()
    velocity = frame[c.BENCH_MOTOR_VELOCITY].to_numpy()
    frame[c.BENCH_MOTOR_TORQUE] -= 2.0 * DRAG * velocity  # torque now falls with speed
    identifier = TransmissionIdentifier().fit(frame)
    assert identifier.model_.dynamic is None
    assert "negative" in str(identifier.dynamic_error_)


def test_cli_writes_a_version_2_model_and_the_friction_figure(tmp_path: Path, capsys) -> None:
    bench = tmp_path / "bench.csv"
    synthetic_bench().to_csv(bench, index=False)
    model_path, figure = tmp_path / "model.json", tmp_path / "friction.png"
    assert main(["identify", str(bench), "-o", str(model_path), "--friction-figure", str(figure),
                 "--imu-latency-ms", "35"]) == 0
    out = capsys.readouterr().out
    assert "Dynamic compensation" in out and re.search(r"drag (39\.[5-9]|40\.[0-4])\d mNm", out)
    assert json.loads(model_path.read_text())["version"] == 2
    model = load_model(model_path)
    assert model.dynamic is not None and model.dynamic.imu_latency_s == 0.035
    assert figure.stat().st_size > 10_000
    assert main(["identify", str(bench), "-o", str(tmp_path / "paper.json"), "--paper-only"]) == 0
    assert load_model(tmp_path / "paper.json").dynamic is None
    assert main(["identify", str(bench), "-o", str(tmp_path / "x.json"), "--imu-latency-ms", "900"]) == 1
    assert "--imu-latency-ms" in capsys.readouterr().err
