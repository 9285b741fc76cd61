"""The IMU's latency identified from the bench's latency segment (issue 28, item 2)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bowden.cli import main
from bowden.errors import FitError
from bowden.identify.latency import identify_imu_latency
from bowden.model.model_file import load_model
from bowden.protocol.bench import LatencyChirp
from bowden.sim.bench_latency import (
    ENCODER_ELEVATION,
    IMU_ELEVATION,
    TIME,
    run_latency_segment,
)
from bowden.sim.parameters import SuitParameters
from bowden.sim.plant_family_structural import noisy_imu


@pytest.mark.parametrize("latency_s", [0.005, 0.015, 0.033, 0.05, 0.08])
def test_latency_within_3_ms_over_5_to_80_ms_with_three_times_the_noise(latency_s: float) -> None:
    suit = SuitParameters(imu=noisy_imu(latency_s, 3.0))
    segment = run_latency_segment(suit, LatencyChirp(duration_s=8.0), seed=int(1e3 * latency_s))
    estimate = identify_imu_latency(segment[TIME].to_numpy(), segment[IMU_ELEVATION].to_numpy(),
                                    segment[ENCODER_ELEVATION].to_numpy())
    assert estimate.latency_s == pytest.approx(latency_s, abs=0.003)
    assert estimate.offset_rad == pytest.approx(suit.imu.elevation_bias_rad, abs=math.radians(0.2))


def test_sub_sample_delay_of_a_hand_made_signal() -> None:
    # 200 Hz samples, a 1.3 Hz sine delayed by 23.7 ms (not a multiple of the 5 ms sample period).
    t = np.arange(0.0, 6.0, 0.005)
    encoder = 1.0 + 0.3 * np.sin(2 * np.pi * 1.3 * t)
    imu = 1.0 + 0.3 * np.sin(2 * np.pi * 1.3 * (t - 0.0237))
    assert identify_imu_latency(t, imu, encoder).latency_s == pytest.approx(0.0237, abs=2e-4)


def test_an_arm_that_did_not_move_is_refused() -> None:
    t = np.arange(0.0, 4.0, 0.005)
    still = np.full(t.size, 1.0)
    with pytest.raises(FitError, match=r"moved 0\.0°"):
        identify_imu_latency(t, still, still)


def test_identify_cli_stores_the_identified_latency(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from tests.identify.test_dynamic_identification import synthetic_bench

    bench, latency_csv, model_path = tmp_path / "bench.csv", tmp_path / "latency.csv", tmp_path / "model.json"
    synthetic_bench().to_csv(bench, index=False)
    run_latency_segment(SuitParameters(imu=noisy_imu(0.022, 1.0)), LatencyChirp(duration_s=6.0)).to_csv(
        latency_csv, index=False
    )
    assert main(["identify", str(bench), "-o", str(model_path), "--latency-recording", str(latency_csv)]) == 0
    dynamic = load_model(model_path).dynamic
    assert dynamic is not None
    assert dynamic.imu_latency_s == pytest.approx(0.022, abs=0.003)
    assert "IMU latency identified" in capsys.readouterr().out
    latency_csv.write_text("time_s,elevation_rad\n0,1\n")
    assert main(["identify", str(bench), "-o", str(model_path), "--latency-recording", str(latency_csv)]) == 1
    assert "--latency-recording" in capsys.readouterr().err
