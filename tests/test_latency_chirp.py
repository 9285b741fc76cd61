"""The bench protocol's latency chirp (protocol/bench.py ``LatencyChirp``), the one definition both
benches run: its trajectory against hand values and its own derivative, scalars and arrays alike,
and its checks in words a user of ``bowden bench run --chirp-s`` can act on."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bowden.cli import main
from bowden.errors import ParameterError
from bowden.protocol.bench import LatencyChirp

# 0.25 → 0.75 Hz over 10 s: sweep rate 0.05 Hz/s, so at t = 5 s the phase is 2π(0.25·5 + 0.025·25)
# = 3.75π (sin −√2/2, cos √2/2) and the angular frequency 2π(0.25 + 0.05·5) = π rad/s.
CHIRP = LatencyChirp(centre_rad=1.0, amplitude_rad=0.2, start_hz=0.25, end_hz=0.75, duration_s=10.0)


def test_mid_chirp_values_by_hand() -> None:
    theta, theta_d = CHIRP.elevation(5.0)
    assert theta == pytest.approx(1.0 - 0.2 * math.sqrt(0.5), abs=1e-12)
    assert theta_d == pytest.approx(0.2 * math.pi * math.sqrt(0.5), abs=1e-12)


def test_at_rest_at_the_centre_before_and_after() -> None:
    for t in (-1.0, 0.0, 10.0, 11.0):
        assert CHIRP.elevation(t) == pytest.approx((1.0, 0.0), abs=1e-12)


def test_the_velocity_is_the_elevations_derivative_through_the_fades() -> None:
    t = np.linspace(0.0, 10.0, 100_001)
    theta, theta_d = CHIRP.elevation(t)
    numeric = np.gradient(theta, t)
    inside = (np.abs(t - 1.0) > 1e-3) & (np.abs(t - 9.0) > 1e-3)  # the fades' kinks
    assert np.allclose(numeric[1:-1][inside[1:-1]], theta_d[1:-1][inside[1:-1]], atol=1e-5)


def test_a_time_gives_floats_and_an_array_gives_the_same_numbers() -> None:
    t = np.linspace(-0.5, 10.5, 89)
    theta, theta_d = CHIRP.elevation(t)
    one_by_one = [CHIRP.elevation(float(x)) for x in t]
    assert all(type(a) is float and type(b) is float for a, b in one_by_one)
    assert np.allclose(np.array(one_by_one), np.column_stack([theta, theta_d]), rtol=0.0, atol=1e-12)


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"duration_s": 0.5},
         r"^--chirp-s must be in \[2, 120\] s \(the latency chirp's duration\), got 0\.5$"),
        ({"duration_s": math.nan}, r"^--chirp-s .* got nan$"),
        ({"centre_rad": 1.9}, r"^the latency chirp must stay within 0°–115°, got .*°$"),
        ({"start_hz": 2.0}, r"^the latency chirp's frequencies must rise within 0\.05–5 Hz, got 2 → 2 Hz$"),
        ({"holding_torque_nm": 5.0},
         r"^the latency chirp's holding torque must be in \[0\.05, 2\] Nm, got 5$"),
    ],
)
def test_a_bad_chirp_is_named_in_words_not_class_names(fields: dict[str, float], message: str) -> None:
    with pytest.raises(ParameterError, match=message):
        LatencyChirp(**fields)


@pytest.mark.parametrize("value", ["0.5", "nan", "1e9"])
def test_a_bad_chirp_s_is_one_line_naming_the_flag(value: str, tmp_path, capsys) -> None:
    # Refused while the configuration is built, before any device opens.
    code = main(["bench", "run", "--backend", "sim", "-o", str(tmp_path / "b.csv"), "--chirp-s", value])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err, err
    assert len(err.strip().splitlines()) == 1 and "--chirp-s" in err, err
    assert not (tmp_path / "b.csv").exists()
