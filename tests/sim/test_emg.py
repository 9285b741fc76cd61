"""Synthetic sEMG: spectrum mostly within 20–400 Hz, envelope follows activation, ECG where expected."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from bowden.contracts import ECG_CONTAMINATED_MUSCLES, MUSCLES
from bowden.sim import emg_synthesize, muscle_activations

RATE = 2000.0


def activation_profile(t: np.ndarray) -> np.ndarray:
    act = np.zeros((t.size, len(MUSCLES)))
    for m in range(len(MUSCLES)):
        act[:, m] = 0.05 + 0.3 * (0.5 + 0.5 * np.sin(2 * np.pi * 0.25 * t + m))
    return act


def synthesize(seed: int = 0, ecg: float = 0.3) -> tuple[np.ndarray, np.ndarray, object]:
    t = np.arange(0, 20.0, 0.002)
    act = activation_profile(t)
    frame = emg_synthesize(t, act, gains=(1.0,) * 8, heart_rate_bpm=70.0, ecg_amplitude=ecg, seed=seed)
    return t, act, frame


def test_spectrum_is_mostly_between_20_and_400_hz() -> None:
    _, _, frame = synthesize()
    for muscle in ("anterior_deltoid", "posterior_deltoid", "triceps"):
        f, pxx = signal.welch(frame[muscle].to_numpy(), fs=RATE, nperseg=2048)
        inside = pxx[(f >= 20) & (f <= 400)].sum() / pxx.sum()
        assert inside > 0.9, muscle


def test_envelope_follows_activation() -> None:
    t, act, frame = synthesize(ecg=0.0)
    sos = signal.butter(3, [20, 400], btype="bandpass", fs=RATE, output="sos")
    window = int(0.1 * RATE)
    for m, muscle in enumerate(MUSCLES):
        rectified = np.abs(signal.sosfiltfilt(sos, frame[muscle].to_numpy()))
        envelope = np.sqrt(np.convolve(rectified**2, np.ones(window) / window, mode="same"))
        reference = np.interp(frame["time_s"].to_numpy(), t, act[:, m])
        inner = slice(window, -window)
        r = np.corrcoef(envelope[inner], reference[inner])[0, 1]
        assert r > 0.95, muscle


def test_ecg_only_on_chest_and_back_muscles() -> None:
    t = np.arange(0, 10.0, 0.002)
    rest = np.full((t.size, len(MUSCLES)), 0.01)
    frame = emg_synthesize(t, rest, gains=(1.0,) * 8, heart_rate_bpm=60.0, ecg_amplitude=1.0, seed=2)
    for muscle in MUSCLES:
        x = frame[muscle].to_numpy()
        if muscle in ECG_CONTAMINATED_MUSCLES:
            peaks, _ = signal.find_peaks(x, height=0.5e-3, distance=int(0.3 * RATE))
            assert 8 <= peaks.size <= 12  # ≈ one beat per second
        else:
            assert np.max(np.abs(x)) < 0.2e-3


def test_same_seed_same_signal() -> None:
    assert synthesize(4)[2].equals(synthesize(4)[2])


def test_agonists_work_while_holding_the_arm_up_and_antagonists_when_pulled_down() -> None:
    n = 500
    th = np.full(n, np.pi / 2)
    lifting = muscle_activations(np.full(n, 10.0), th, np.zeros(n), sample_rate_hz=500.0, max_torque_nm=44.0)
    pulling = muscle_activations(np.full(n, -10.0), th, np.zeros(n), sample_rate_hz=500.0, max_torque_nm=44.0)
    ad, pd = MUSCLES.index("anterior_deltoid"), MUSCLES.index("posterior_deltoid")
    assert lifting[-1, ad] > 0.15 > lifting[-1, pd]
    assert pulling[-1, pd] > 0.15 > pulling[-1, ad]
    # Eccentric lowering needs less activation for the same torque.
    lowering = muscle_activations(
        np.full(n, 10.0), th, np.full(n, -1.0), sample_rate_hz=500.0, max_torque_nm=44.0
    )
    assert lowering[-1, ad] < lifting[-1, ad]
    assert lifting[-1, ad] == pytest.approx(0.01 + 1.0 * 10 / 44 + 0.6 * 0.01, rel=1e-3)
