import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from monalysa.quality.smoothness import sparc as monalysa_sparc

from bowden.analysis import SparcParameters, sparc
from bowden.errors import ParameterError, RecordingError


def test_published_gaussian_value():
    # Balasubramanian et al. 2015 ("Methods"): exp(-5 t²), t = -1…0.99 step 0.01, 100 Hz.
    t = np.arange(-100, 100) / 100.0
    assert sparc(np.exp(-5.0 * t**2), 100.0) == pytest.approx(-1.41403, abs=1e-4)


@pytest.mark.parametrize(("rate_hz", "expected"), [(100.0, -1.40583), (1000.0, -1.40243)])
def test_published_minimum_jerk_values(rate_hz, expected):
    tau = np.arange(int(rate_hz)) / rate_hz  # a 1 s movement
    speed = 30.0 * tau**2 * (1.0 - tau) ** 2  # exact derivative of the minimum-jerk position
    assert sparc(speed, rate_hz) == pytest.approx(expected, abs=1e-4)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(8, 3000),
    rate_hz=st.floats(25.0, 5000.0),
    padlevel=st.integers(0, 6),
    fc_hz=st.floats(1.0, 12.0),
    threshold=st.floats(0.01, 0.5),
)
def test_matches_monalysa_on_random_signals(seed, n, rate_hz, padlevel, fc_hz, threshold):
    rng = np.random.default_rng(seed)
    speed = np.abs(np.cumsum(rng.standard_normal(n))) + rng.random(n)
    ours = sparc(
        speed, rate_hz, SparcParameters(padlevel=padlevel, fc_hz=fc_hz, amplitude_threshold=threshold)
    )
    theirs = monalysa_sparc(speed, rate_hz, padlevel=padlevel, fc=fc_hz, amp_th=threshold)[0]
    assert ours == pytest.approx(theirs, abs=1e-9)


def test_scale_invariance_and_smoother_is_closer_to_zero():
    tau = np.linspace(0.0, 1.0, 201)
    bell = 30.0 * tau**2 * (1.0 - tau) ** 2
    two_bells = np.concatenate([bell, bell[1:]])
    assert sparc(3.7 * bell, 200.0) == pytest.approx(sparc(bell, 200.0), abs=1e-12)
    assert sparc(two_bells, 200.0) < sparc(bell, 200.0)


def test_refuses_bad_input():
    with pytest.raises(RecordingError, match="zero everywhere"):
        sparc(np.zeros(50), 100.0)
    with pytest.raises(RecordingError, match="not finite at sample 3"):
        sparc(np.array([1.0, 2.0, 3.0, np.nan]), 100.0)
    with pytest.raises(ParameterError, match="twice fc_hz"):
        sparc(np.ones(50), 15.0)
    with pytest.raises(ParameterError, match="amplitude_threshold"):
        SparcParameters(amplitude_threshold=1.5)
