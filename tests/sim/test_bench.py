"""The simulated mannequin bench: contract format, CLI, and identification recovers the plant."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bowden import contracts as c
from bowden.cli import main
from bowden.errors import ParameterError
from bowden.identify import TransmissionIdentifier
from bowden.model.transmission import slopes_from_friction
from bowden.sim import BenchProtocol, SimulatedSuit, SuitParameters, generate_cohort, run_bench

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


def steady_sliding_intercept_nm(suit: SuitParameters, spool_speed_rad_s: float, sigma: int) -> float:
    """Quasi-static intercept of the motor-torque line at one constant spool speed (hand-derived).

    Steady sliding (constant speed, no acceleration): the sheath node balances
    (1 − σk)·T_in − (1 + σk)·T_out = c_v·σ·R·|ω| and the rotor R·T_in + σ·(τ_c + b·|ω|) = c·τ_reported,
    so τ_reported = R(1 + σk)/(1 − σk)/c · T_out + σ·[τ_c + (b + R²·c_v/(1 − σk))·|ω|]/c. The slope does
    not depend on the speed; the viscous terms move only the intercept.
    """
    m, k, r = suit.motor, suit.sheath.kinetic_coefficient, suit.motor.spool_radius_m
    viscous = m.viscous_friction_nms_rad + r * r * suit.sheath.viscous_coefficient_ns_m / (1 - sigma * k)
    return sigma * (m.coulomb_friction_nm + viscous * spool_speed_rad_s) / m.torque_constant_ratio


def test_identification_recovers_the_plants_friction(recording: pd.DataFrame) -> None:
    suit = SuitParameters()
    model = TransmissionIdentifier().fit(recording).model_
    raising, lowering = slopes_from_friction(suit.sheath.kinetic_coefficient, suit.motor.spool_radius_m)
    assert model.raising.slope_m == pytest.approx(raising, rel=0.03)
    assert model.lowering.slope_m == pytest.approx(lowering, rel=0.03)
    # The intercepts carry the motor's Coulomb friction and the speed-proportional drags, with the sign
    # of the motion: a line pooled over the protocol's speeds lies between the slowest and the fastest.
    for line, sigma in ((model.raising, 1), (model.lowering, -1)):
        speeds = (min(SHORT.spool_speeds_rad_s), max(SHORT.spool_speeds_rad_s))
        ends = [steady_sliding_intercept_nm(suit, w, sigma) for w in speeds]
        assert min(ends) - 0.02 <= line.intercept_nm <= max(ends) + 0.02


def per_speed_lines(
    suit: SuitParameters, protocol: BenchProtocol, seed: int
) -> dict[float, tuple[float, float, float, float]]:
    """Identify one pair of lines per spool speed (trial numbers run load, speed, repetition, direction)."""
    frame = run_bench(suit, protocol, seed=seed)
    n_speeds, reps = len(protocol.spool_speeds_rad_s), protocol.repetitions
    speed_index = (frame[c.BENCH_TRIAL] // (2 * reps)) % n_speeds
    lines = {}
    for i, speed in enumerate(protocol.spool_speeds_rad_s):
        model = TransmissionIdentifier().fit(frame[speed_index == i]).model_
        raising, lowering = model.raising, model.lowering
        lines[speed] = (raising.slope_m, raising.intercept_nm, lowering.slope_m, lowering.intercept_nm)
    return lines


def test_sheath_drag_moves_only_the_intercepts_by_the_derived_amount() -> None:
    # The same bench with and without the sheath's viscous drag, one line pair per speed: the drag
    # leaves every slope alone and shifts each intercept by σ·R²·c_v·|ω|/(1 − σk) (see
    # steady_sliding_intercept_nm). Differencing cancels everything else the bench adds to the
    # intercepts (motor friction, the distal damper's share while the tension follows r(θ)).
    with_drag = SuitParameters()
    assert with_drag.sheath.viscous_coefficient_ns_m > 0.0
    without = SuitParameters(sheath=replace(with_drag.sheath, viscous_coefficient_ns_m=0.0))
    protocol = BenchProtocol(spool_speeds_rad_s=(1.0, 3.0), loads_nm=(1.0, 3.0), repetitions=1)
    dragged, clean = per_speed_lines(with_drag, protocol, 2), per_speed_lines(without, protocol, 2)
    for speed in protocol.spool_speeds_rad_s:
        r_slope, r_icpt, l_slope, l_icpt = dragged[speed]
        r_slope0, r_icpt0, l_slope0, l_icpt0 = clean[speed]
        assert r_slope == pytest.approx(r_slope0, rel=0.005) and l_slope == pytest.approx(l_slope0, rel=0.005)
        for sigma, shift in ((1, r_icpt - r_icpt0), (-1, l_icpt - l_icpt0)):
            expected = steady_sliding_intercept_nm(with_drag, speed, sigma)
            expected -= steady_sliding_intercept_nm(without, speed, sigma)
            assert shift == pytest.approx(expected, rel=0.1)


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


def test_cli_refuses_a_bad_seed_or_output_before_simulating(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["bench", "simulate", "--speeds", "2", "--loads", "2", "--repetitions", "1", "--quiet"]
    assert main([*args, "-o", str(tmp_path / "bench.csv"), "--seed", "-1"]) == 1
    assert "seed must be an integer in [0, 4294967295], got -1" in capsys.readouterr().err
    missing = tmp_path / "no-such-dir" / "bench.csv"
    assert main([*args, "-o", str(missing)]) == 1
    assert "no-such-dir does not exist" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("seed", [-1, 2**32, 1.5, True])
def test_seeds_numpy_would_reject_are_refused_by_name(seed: object) -> None:
    with pytest.raises(ParameterError, match="seed must be an integer"):
        run_bench(seed=seed)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="seed must be an integer"):
        generate_cohort(seed)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="seed must be an integer"):
        SimulatedSuit(seed=seed)  # type: ignore[arg-type]
