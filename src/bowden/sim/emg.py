"""Synthetic surface EMG: band-limited noise shaped by activation, baseline noise and ECG artefacts.

Surface EMG is well described as zero-mean Gaussian noise whose standard deviation follows muscle
activation and whose spectrum is that of the motor-unit action potentials seen through the tissue,
mostly 20–400 Hz with a peak near 80–120 Hz (De Luca 1997, J Appl Biomech 13:135; Hogan & Mann 1980,
IEEE TBME 27:382). Here: unit-variance white noise through a 2nd-order Butterworth band-pass
(30–250 Hz; its skirts put most power within 20–400 Hz), times ``gain·activation·0.5 mV``, plus
amplifier noise (3 µV RMS) and, on the chest and back muscles, an ECG (P–QRS–T as Gaussian
waves, McSharry et al. 2003, IEEE TBME 50:289) at the participant's heart rate with beat-to-beat
variability.

Beyond the noise of the carrier itself, a recorded sEMG amplitude varies between trials and between
repetitions for reasons a muscle model does not see: the electrode-skin interface drifts over a
session (sweat lowers the impedance), the electrode moves over the muscle, the participant shifts
its posture or strategy between blocks, and no two repetitions recruit alike. :func:`amplitude_factors`
draws these as mean-one log-normal factors per muscle: one per trial and one per repetition
(sizes and sources: :class:`bowden.sim.participants.VirtualParticipant`, ``emg_trial_sd`` and
``emg_repetition_sd``; docs/simulation.md, "Amplitude variability").
"""

from __future__ import annotations

import functools

import numpy as np
import pandas as pd
from numpy.typing import NDArray
from scipy import signal

from bowden.contracts import ECG_CONTAMINATED_MUSCLES, EMG_RATE_HZ, MUSCLES
from bowden.errors import ParameterError

FULL_ACTIVATION_V = 0.5e-3  # sEMG RMS at full activation, V
BASELINE_NOISE_V = 3e-6
ECG_PEAK_V = 1.0e-3  # R-wave peak at ecg_amplitude = 1, V
CARRIER_BAND_HZ = (30.0, 250.0)
# (relative time of the wave to the R peak in s, amplitude relative to R, width in s), McSharry 2003.
_ECG_WAVES = ((-0.20, 0.12, 0.025), (-0.03, -0.15, 0.010), (0.0, 1.0, 0.010),
              (0.03, -0.25, 0.010), (0.26, 0.30, 0.040))
# Stream of a trial's seed that draws its amplitude factors (apart from the carrier's noise, so
# the factors' sizes change no other draw).
_AMPLITUDE_STREAM = 7411


@functools.lru_cache(maxsize=8)
def _carrier_filter(rate_hz: float) -> NDArray[np.float64]:
    # Designed once per rate: a study synthesises eight channels for every one of its trials.
    return np.asarray(signal.butter(2, CARRIER_BAND_HZ, btype="bandpass", fs=rate_hz, output="sos"))


def emg_carrier(n: int, rate_hz: float, rng: np.random.Generator) -> NDArray[np.float64]:
    """Unit-RMS band-limited Gaussian noise with the sEMG spectrum."""
    sos = _carrier_filter(float(rate_hz)).copy()  # SciPy's filter wants a writable array
    warm = int(0.2 * rate_hz)  # let the filter forget its zero initial state
    carrier = signal.sosfilt(sos, rng.standard_normal(n + warm))[warm:]
    rms = float(np.sqrt(np.mean(carrier**2))) if n > 0 else 1.0
    return np.asarray(carrier / rms, dtype=np.float64)


def ecg_artefact(
    time_s: NDArray[np.float64], heart_rate_bpm: float, amplitude: float, rng: np.random.Generator
) -> NDArray[np.float64]:
    """ECG as seen by a chest or back electrode (V), beats at ``heart_rate_bpm`` with 4 % RR variability."""
    out = np.zeros_like(time_s)
    if time_s.size == 0 or amplitude == 0.0:
        return out
    mean_rr = 60.0 / heart_rate_bpm
    beat = time_s[0] + rng.uniform(0.0, mean_rr)
    while beat < time_s[-1] + 0.5:
        for offset, relative, width in _ECG_WAVES:
            centre = beat + offset
            lo, hi = np.searchsorted(time_s, [centre - 5 * width, centre + 5 * width])
            if hi > lo:
                out[lo:hi] += relative * np.exp(-0.5 * ((time_s[lo:hi] - centre) / width) ** 2)
        beat += mean_rr * (1.0 + 0.04 * rng.standard_normal())
    return out * amplitude * ECG_PEAK_V


def mean_one_lognormal(
    rng: np.random.Generator, log_sd: float, shape: tuple[int, ...]
) -> NDArray[np.float64]:
    """Log-normal factors of log-SD ``log_sd`` and mean exactly one in expectation (exp(σz − σ²/2)).

    Always draws ``shape`` normals, so ``log_sd = 0`` (all ones) leaves the generator where any
    other size would.
    """
    z = rng.standard_normal(shape)
    return np.asarray(np.exp(log_sd * z - 0.5 * log_sd**2), dtype=np.float64)


def amplitude_factors(
    repetition_index: NDArray[np.int64],
    *,
    trial_sd: float,
    repetition_sd: float,
    seed: int,
    n_muscles: int = len(MUSCLES),
) -> NDArray[np.float64]:
    """Multiplicative sEMG amplitude factors, shape (samples, muscles): one per trial and muscle
    times one per repetition and muscle.

    Parameters
    ----------
    repetition_index
        Repetition (0-based) of each sample, −1 outside the movement (there only the trial's factor).
    trial_sd, repetition_sd
        Log-normal SDs of the trial's and of each repetition's factor (each of mean one).
    seed
        The trial's seed (the factors are drawn from a stream of their own).
    """
    if not (0.0 <= trial_sd <= 2.0 and 0.0 <= repetition_sd <= 2.0):
        raise ParameterError(f"amplitude SDs must be in [0, 2], got {trial_sd}, {repetition_sd}")
    index = np.asarray(repetition_index, dtype=np.int64)
    rng = np.random.default_rng([seed, _AMPLITUDE_STREAM])
    trial = mean_one_lognormal(rng, trial_sd, (n_muscles,))
    n_repetitions = int(index.max()) + 1 if index.size else 0
    per_repetition = mean_one_lognormal(rng, repetition_sd, (max(n_repetitions, 0), n_muscles))
    out = np.tile(trial, (index.size, 1))
    inside = index >= 0
    out[inside] *= per_repetition[index[inside]]
    return out


def emg_synthesize(
    activation_time_s: NDArray[np.float64],
    activations: NDArray[np.float64],
    *,
    gains: tuple[float, ...] | NDArray[np.float64],
    heart_rate_bpm: float,
    ecg_amplitude: float,
    seed: int,
    rate_hz: float = EMG_RATE_HZ,
    factors: NDArray[np.float64] | None = None,
) -> pd.DataFrame:
    """Raw sEMG (V) at ``rate_hz`` for the eight muscles from their activations.

    Parameters
    ----------
    activation_time_s, activations
        Times (s, increasing) and activations, shape (n, 8) in the order of ``contracts.MUSCLES``.
    gains
        Per-muscle amplitude gains (electrode, skin).
    heart_rate_bpm, ecg_amplitude
        ECG artefact on ``contracts.ECG_CONTAMINATED_MUSCLES``.
    seed
        Seed of the noise (the same seed gives the same signal).
    factors
        Multiplicative amplitude factors at the activation times, shape of ``activations``
        (:func:`amplitude_factors`); None: all one.

    Returns
    -------
    DataFrame with ``time_s`` and one column per muscle.
    """
    t_act = np.asarray(activation_time_s, dtype=np.float64)
    act = np.asarray(activations, dtype=np.float64)
    if act.ndim != 2 or act.shape != (t_act.size, len(MUSCLES)):
        raise ParameterError(f"activations must have shape (len(time), {len(MUSCLES)}), got {act.shape}")
    if t_act.size < 2 or np.any(np.diff(t_act) <= 0):
        raise ParameterError("activation times must be increasing with at least two samples")
    if len(gains) != len(MUSCLES):
        raise ParameterError(f"gains needs {len(MUSCLES)} values, got {len(gains)}")
    if factors is not None:
        if np.shape(factors) != act.shape:
            raise ParameterError(f"amplitude factors must have the activations' shape {act.shape}")
        act = act * np.asarray(factors, dtype=np.float64)
    rng = np.random.default_rng(seed)
    n = int(np.floor((t_act[-1] - t_act[0]) * rate_hz)) + 1
    time_s = t_act[0] + np.arange(n) / rate_hz
    columns: dict[str, NDArray[np.float64]] = {"time_s": time_s}
    ecg = ecg_artefact(time_s, heart_rate_bpm, ecg_amplitude, rng)
    for m, muscle in enumerate(MUSCLES):
        amplitude = np.interp(time_s, t_act, act[:, m]) * float(gains[m]) * FULL_ACTIVATION_V
        emg = amplitude * emg_carrier(n, rate_hz, rng) + BASELINE_NOISE_V * rng.standard_normal(n)
        if muscle in ECG_CONTAMINATED_MUSCLES:
            emg = emg + ecg
        columns[muscle] = emg
    return pd.DataFrame(columns)
