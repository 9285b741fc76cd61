"""The simulated mannequin bench: contract format, CLI, and identification recovers the plant."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bowden import contracts as c
from bowden.cli import main
from bowden.errors import ParameterError
from bowden.identify import TransmissionIdentifier
from bowden.model.transmission import slopes_from_friction
from bowden.sim import BenchProtocol, SuitParameters, run_bench

SHORT = BenchProtocol(spool_speeds_rad_s=(1.0, 3.0), loads_nm=(1.0, 3.0), repetitions=1)


@pytest.fixture(scope="module")
def recording() -> pd.DataFrame:
    return run_bench(protocol=SHORT, seed=1)


def test_recording_follows_the_contract(recording: pd.DataFrame) -> None:
    assert list(recording.columns) == [*c.BENCH_COLUMNS, c.BENCH_TRIAL]
    assert np.all(np.diff(recording[c.BENCH_TIME]) > 0)
    assert recording[c.BENCH_TRIAL].nunique() == SHORT.n_strokes
    assert not recording.isna().any().any()
    # Strokes cover the protocol's range and the spool runs both ways at the commanded speeds.
    elevation = recording[c.BENCH_ELEVATION]
    assert elevation.min() < math.radians(25.0) and elevation.max() > math.radians(105.0)
    velocity = recording[c.BENCH_MOTOR_VELOCITY]
    assert velocity[velocity > 2.0].median() == pytest.approx(3.0, abs=0.1)
    assert velocity[velocity < -2.0].median() == pytest.approx(-3.0, abs=0.1)


def test_identification_recovers_the_plants_friction(recording: pd.DataFrame) -> None:
    suit = SuitParameters()
    model = TransmissionIdentifier().fit(recording).model_
    raising, lowering = slopes_from_friction(suit.sheath.kinetic_coefficient, suit.motor.spool_radius_m)
    assert model.raising.slope_m == pytest.approx(raising, rel=0.03)
    assert model.lowering.slope_m == pytest.approx(lowering, rel=0.03)
    # The intercepts carry the motor's Coulomb friction, with the sign of the motion.
    coulomb = suit.motor.coulomb_friction_nm
    assert model.raising.intercept_nm == pytest.approx(coulomb, abs=0.03)
    assert model.lowering.intercept_nm == pytest.approx(-coulomb, abs=0.03)


def test_cli_writes_csv_and_parquet(tmp_path: Path) -> None:
    args = ["bench", "simulate", "--speeds", "2", "--loads", "2", "--repetitions", "1", "--quiet"]
    assert main([*args, "-o", str(tmp_path / "bench.csv"), "--seed", "3"]) == 0
    assert main([*args, "-o", str(tmp_path / "bench.parquet"), "--seed", "3"]) == 0
    csv = pd.read_csv(tmp_path / "bench.csv")
    parquet = pd.read_parquet(tmp_path / "bench.parquet")
    assert list(csv.columns) == [*c.BENCH_COLUMNS, c.BENCH_TRIAL]
    pd.testing.assert_frame_equal(csv, parquet, check_exact=False, rtol=1e-12)
    assert main([*args, "-o", str(tmp_path / "bench.txt")]) == 1


def test_bad_protocol_names_the_field() -> None:
    with pytest.raises(ParameterError, match="spool_speeds_rad_s"):
        BenchProtocol(spool_speeds_rad_s=(100.0,))
