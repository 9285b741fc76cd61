import numpy as np
import pytest
from scipy import signal as sps

from bowden.analysis import EmgSignal, emg_envelope, emg_filter, emg_rectify
from bowden.analysis.emg.filter import butterworth_bandpass_sos
from bowden.errors import ParameterError, RecordingError

from .conftest import RATE_HZ, emg_noise, smooth_activation


def _sine(freq_hz: float, seconds: float = 4.0, amplitude: float = 1.0) -> EmgSignal:
    t = np.arange(int(seconds * RATE_HZ)) / RATE_HZ
    return EmgSignal(values=amplitude * np.sin(2 * np.pi * freq_hz * t), rate_hz=RATE_HZ)


def _steady_gain(freq_hz: float) -> float:
    out = emg_filter(_sine(freq_hz)).values[:, 0]
    middle = out[int(1.0 * RATE_HZ) : int(3.0 * RATE_HZ)]  # away from the edge transients
    return float(np.sqrt(2.0) * np.sqrt(np.mean(middle**2)))


@pytest.mark.parametrize("freq_hz", [20.0, 400.0])
def test_zero_phase_bandpass_is_minus_6_db_at_both_cutoffs(freq_hz):
    # A single pass of butter(3) is -3 dB at the band edges; forward-backward squares |H| -> 1/2.
    gain_db = 20.0 * np.log10(_steady_gain(freq_hz))
    assert gain_db == pytest.approx(20.0 * np.log10(0.5), abs=0.05)  # -6.02 dB


def test_single_pass_design_is_minus_3_db_and_filtfilt_squares_it():
    sos = butterworth_bandpass_sos(RATE_HZ)
    _, h = sps.sosfreqz(sos, worN=[20.0, 400.0], fs=RATE_HZ)
    assert np.abs(h) == pytest.approx([1 / np.sqrt(2)] * 2, rel=1e-9)
    assert _steady_gain(100.0) == pytest.approx(1.0, abs=0.01)  # pass band
    assert _steady_gain(5.0) < 0.01  # 2 octaves below: 6th-order effective roll-off
    assert _steady_gain(900.0) < 0.01


def test_filter_adds_no_delay():
    rng = np.random.default_rng(3)
    x = EmgSignal(values=emg_noise(20000, rng), rate_hz=RATE_HZ)
    y = emg_filter(x).values[:, 0]
    lags = np.arange(-20, 21)
    xc = [np.dot(x.values[1000:-1000, 0], np.roll(y, lag)[1000:-1000]) for lag in lags]
    assert lags[int(np.argmax(xc))] == 0


def test_envelope_of_unit_sine_is_0_7071():
    env = emg_envelope(emg_rectify(_sine(50.0))).values[:, 0]
    interior = env[200:-200]
    assert interior == pytest.approx(np.full(interior.size, 1 / np.sqrt(2)), abs=1e-9)
    assert np.sqrt(0.5) == pytest.approx(0.7071, abs=5e-5)


def test_envelope_matches_a_direct_window_loop_including_shrinking_ends():
    rng = np.random.default_rng(7)
    x = rng.standard_normal((600, 2))
    env = emg_envelope(EmgSignal(values=x, rate_hz=1000.0), window_s=0.1).values
    width, back = 100, 50
    for i in (0, 10, 49, 50, 300, 549, 550, 599):
        window = x[max(0, i - back) : min(600, i - back + width)]
        assert env[i] == pytest.approx(np.sqrt(np.mean(window**2, axis=0)), rel=1e-12)


def test_envelope_follows_known_activation(contaminated_emg):
    rng = np.random.default_rng(11)
    n = int(20 * RATE_HZ)
    activation = smooth_activation(n, rng)
    raw = EmgSignal(values=1e-4 * activation * emg_noise(n, rng), rate_hz=RATE_HZ)
    env = emg_envelope(emg_rectify(emg_filter(raw))).values[:, 0]
    r = np.corrcoef(env, activation)[0, 1]
    assert r >= 0.95


def test_filter_refuses_bad_input():
    with pytest.raises(ParameterError, match="Nyquist"):
        emg_filter(EmgSignal(values=np.zeros(1000), rate_hz=500.0))
    x = np.zeros(1000)
    x[10] = np.nan
    with pytest.raises(RecordingError, match="sample 10"):
        emg_filter(EmgSignal(values=x, rate_hz=RATE_HZ, channels=("biceps",)))
    with pytest.raises(RecordingError, match="too short"):
        emg_filter(EmgSignal(values=np.zeros(10), rate_hz=RATE_HZ))
    with pytest.raises(ParameterError, match="window_s"):
        emg_envelope(EmgSignal(values=np.zeros(10), rate_hz=RATE_HZ), window_s=0.0)


def test_signal_container_keeps_rate_and_refuses_non_uniform_time():
    frame = EmgSignal(values=np.ones((5, 2)), rate_hz=2000.0, channels=("a", "b"), start_s=1.0).to_frame()
    back = EmgSignal.from_frame(frame)
    assert back.rate_hz == pytest.approx(2000.0)
    assert back.start_s == 1.0
    assert back.channels == ("a", "b")
    frame.loc[3, "time_s"] += 0.0002
    with pytest.raises(RecordingError, match="row 3"):
        EmgSignal.from_frame(frame)
    caller = np.zeros(4)
    EmgSignal(values=caller, rate_hz=1.0)
    caller[0] = 1.0  # the caller's array stays writable: the signal keeps its own copy
