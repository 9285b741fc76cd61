"""Spectral arc length (SPARC), the smoothness measure of Balasubramanian et al. (2015).

Balasubramanian S., Melendez-Calderon A., Roby-Brami A., Burdet E. (2015) "On the analysis of
movement smoothness", J NeuroEng Rehabil 12:112. Written from that paper's definition ("Methods"):

1. zero-pad the speed profile to 2^(ceil(log2 N) + padlevel) samples and take |FFT|, normalised by
   its maximum (the DC bin for a non-negative speed profile);
2. keep the frequencies up to ``fc_hz`` (10 Hz), and of those the span from the first to the last
   bin whose normalised magnitude is at least ``amplitude_threshold`` (0.05);
3. SPARC = −Σ sqrt((Δf / (f_last − f_first))² + (Δ|V̂|)²), the negated arc length of that curve.

Feed a *speed* profile (|θ̇|, non-negative), not a signed velocity: the method compares the spectrum
of one bell-shaped speed profile with its DC content, and a velocity that changes sign has (almost)
no DC component, so the normalisation by the maximum and the threshold lose their meaning. Values
are negative and closer to zero for smoother movements; the paper flipped the sign for its
statistics. Reference values of the original paper: a Gaussian speed exp(−5t²), t = −1…0.99 step
0.01 at 100 Hz → −1.41403; a minimum-jerk speed of 1 s at 100 Hz → −1.40583 (−1.40243 at 1 kHz).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from bowden.errors import ParameterError, RecordingError


@dataclass(frozen=True, kw_only=True)
class SparcParameters:
    """Settings of :func:`sparc` (defaults: Balasubramanian et al. 2015).

    Parameters
    ----------
    padlevel
        Zero padding: the FFT has 2^(ceil(log2 N) + padlevel) points.
    fc_hz
        Highest frequency considered, Hz (human movement content lies below 10 Hz).
    amplitude_threshold
        Normalised magnitude that bounds the adaptive frequency span.
    """

    padlevel: int = 4
    fc_hz: float = 10.0
    amplitude_threshold: float = 0.05

    def __post_init__(self) -> None:
        if not (isinstance(self.padlevel, int) and 0 <= self.padlevel <= 12):
            raise ParameterError(f"padlevel must be an integer in 0..12, got {self.padlevel!r}")
        if not (math.isfinite(self.fc_hz) and self.fc_hz > 0.0):
            raise ParameterError(f"fc_hz must be positive, got {self.fc_hz}")
        if not (math.isfinite(self.amplitude_threshold) and 0.0 < self.amplitude_threshold < 1.0):
            raise ParameterError(f"amplitude_threshold must be in (0, 1), got {self.amplitude_threshold}")


def sparc(speed: ArrayLike, rate_hz: float, parameters: SparcParameters | None = None) -> float:
    """SPARC of a uniformly sampled speed profile (dimensionless, ≤ 0; closer to 0 is smoother).

    Parameters
    ----------
    speed
        Movement speed, any unit (SPARC is invariant to amplitude scaling), 1-D, ≥ 2 samples.
    rate_hz
        Sampling rate, Hz; must exceed 2·fc_hz so that the spectrum up to fc_hz is not aliased.
    parameters
        Padding, cut-off and threshold; defaults as published.
    """
    params = parameters or SparcParameters()
    x = np.asarray(speed, dtype=np.float64)
    if x.ndim != 1 or x.size < 2:
        raise RecordingError(f"sparc needs a 1-D speed profile of at least 2 samples, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise RecordingError(
            f"sparc: speed is not finite at sample {int(np.flatnonzero(~np.isfinite(x))[0])}"
        )
    if not (math.isfinite(rate_hz) and rate_hz > 2.0 * params.fc_hz):
        raise ParameterError(f"rate_hz ({rate_hz}) must exceed twice fc_hz ({params.fc_hz})")
    n_fft = 2 ** (math.ceil(math.log2(x.size)) + params.padlevel)
    magnitude = np.abs(np.fft.rfft(x, n_fft))
    peak = float(magnitude.max())
    if peak == 0.0:
        raise RecordingError("sparc: the speed profile is zero everywhere (no movement)")
    frequency = np.arange(magnitude.size) * (rate_hz / n_fft)
    keep = frequency <= params.fc_hz
    frequency = frequency[keep]
    magnitude = magnitude[keep] / peak
    above = np.flatnonzero(magnitude >= params.amplitude_threshold)
    first, last = int(above[0]), int(above[-1])
    frequency = frequency[first : last + 1]
    magnitude = magnitude[first : last + 1]
    if frequency.size < 2:
        # A span of one bin has no arc; the curve is a point. Happens only for pathological input.
        return 0.0
    span = frequency[-1] - frequency[0]
    arc = np.sqrt(np.square(np.diff(frequency) / span) + np.square(np.diff(magnitude)))
    return -float(np.sum(arc))
