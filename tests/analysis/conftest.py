"""Synthetic EMG and ECG with known truth for the analysis tests.

EMG: band-limited Gaussian noise whose standard deviation follows a known activation, the usual
amplitude-modulated noise model of sEMG (e.g. Clancy & Hogan 1999). ECG: a sum of Gaussian waves per
beat (P, Q, R, S, T; after McSharry et al. 2003, ECGSYN), with beat-to-beat changes of heart rate,
amplitude and QRS width, so that an adaptive template has something to adapt to.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy import signal as sps

RATE_HZ = 2000.0

# (amplitude mV, centre s, width s) of the P, Q, R, S, T waves relative to the R-peak.
_WAVES = (
    (0.12, -0.20, 0.025),
    (-0.15, -0.028, 0.008),
    (1.00, 0.0, 0.010),
    (-0.30, 0.028, 0.008),
    (0.30, 0.30, 0.050),
)


@dataclass(frozen=True)
class ContaminatedEmg:
    """EMG, ECG and their sum, V, plus the truth the tests compare against."""

    emg_v: NDArray[np.float64]
    ecg_v: NDArray[np.float64]
    r_peaks: NDArray[np.int64]
    activation: NDArray[np.float64]

    @property
    def raw_v(self) -> NDArray[np.float64]:
        return self.emg_v + self.ecg_v


def emg_noise(n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """Unit-variance sEMG-like noise: white noise band-limited to 30–300 Hz (4th-order Butterworth)."""
    sos = sps.butter(4, [30.0, 300.0], btype="bandpass", fs=RATE_HZ, output="sos")
    x = sps.sosfilt(sos, rng.standard_normal(n + 4000))[4000:]
    return np.asarray(x / x.std(), dtype=np.float64)


def smooth_activation(n: int, rng: np.random.Generator, period_s: float = 2.5) -> NDArray[np.float64]:
    """A smooth positive activation between 0.1 and 1 with a movement-like rhythm."""
    t = np.arange(n) / RATE_HZ
    phase = rng.uniform(0.0, 2.0 * np.pi)
    a = 0.55 + 0.45 * np.sin(2.0 * np.pi * t / period_s + phase) * (0.8 + 0.2 * np.sin(0.37 * t))
    return np.asarray(a, dtype=np.float64)


def ecg_wave(
    n: int, rng: np.random.Generator, *, amplitude_v: float = 1e-3, heart_rate_bpm: float = 72.0
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Synthetic ECG and its R-peak sample indices (variable RR, amplitude, QRS width)."""
    t = np.arange(n) / RATE_HZ
    rr_mean = 60.0 / heart_rate_bpm
    beats = []
    time = 0.35
    while time < t[-1] - 0.35:
        beats.append(time)
        time += rr_mean * (1.0 + 0.06 * rng.standard_normal())
    ecg = np.zeros(n)
    peaks = []
    for r_time in beats:
        gain = amplitude_v * (1.0 + 0.15 * rng.standard_normal())
        qrs_scale = 1.0 + 0.08 * rng.standard_normal()  # QRS width varies from beat to beat
        lo = np.searchsorted(t, r_time - 0.45)
        hi = np.searchsorted(t, r_time + 0.6)
        local = t[lo:hi] - r_time
        for i, (amp, centre, width) in enumerate(_WAVES):
            scale = qrs_scale if 1 <= i <= 3 else 1.0
            ecg[lo:hi] += gain * amp * np.exp(-0.5 * ((local - centre * scale) / (width * scale)) ** 2)
        peaks.append(round(r_time * RATE_HZ))
    return ecg, np.asarray(peaks, dtype=np.int64)


@pytest.fixture
def contaminated_emg() -> Callable[..., ContaminatedEmg]:
    """Factory: ``contaminated_emg(duration_s, seed, emg_rms_v, ecg_amplitude_v)``."""

    def make(
        duration_s: float = 30.0, seed: int = 0, emg_rms_v: float = 100e-6, ecg_amplitude_v: float = 1e-3
    ) -> ContaminatedEmg:
        rng = np.random.default_rng(seed)
        n = int(duration_s * RATE_HZ)
        activation = smooth_activation(n, rng)
        emg = emg_rms_v * activation * emg_noise(n, rng)
        ecg, peaks = ecg_wave(n, rng, amplitude_v=ecg_amplitude_v)
        return ContaminatedEmg(emg_v=emg, ecg_v=ecg, r_peaks=peaks, activation=activation)

    return make
