"""The IMU's latency, identified on the bench instead of assumed (issue 28, item 2).

The controller predicts the elevation across the IMU's latency (:mod:`bowden.model.elevation_estimator`)
and the dynamic compensation switches lines on that prediction, so a wrong latency moves every switch.
The latency segment of the bench protocol (docs/identification.md, "Latency segment") makes it
observable: the mannequin's motor moves the arm along a chirp in position mode while the IMU is
strapped to it, so the mannequin's joint encoder (no latency worth counting: it is read in the same
cycle) and the IMU see the same motion, the IMU later. The latency is the delay that best maps the
encoder's elevation onto the IMU's, by least squares with a constant offset (the strap's bias):
a grid of 0.5 ms, then a parabola through the three best grid points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from bowden.errors import FitError

MAX_LATENCY_S = 0.2  # the model's range (DynamicCompensation.imu_latency_s)
GRID_S = 5e-4
MIN_EXCURSION_RAD = math.radians(5.0)


@dataclass(frozen=True)
class LatencyEstimate:
    """The identified latency, the residual RMS at it and the IMU's constant offset (rad)."""

    latency_s: float
    residual_rms_rad: float
    offset_rad: float


def _cost(time_s: NDArray[np.float64], imu: NDArray[np.float64], encoder: NDArray[np.float64],
          delay_s: float, inside: NDArray[np.bool_]) -> tuple[float, float]:
    """Residual variance of the IMU against the encoder delayed by ``delay_s`` (and the offset)."""
    shifted = np.interp(time_s[inside] - delay_s, time_s, encoder)
    residual = imu[inside] - shifted
    return float(np.var(residual)), float(np.mean(residual))


def identify_imu_latency(
    time_s: NDArray[np.float64], imu_elevation_rad: NDArray[np.float64],
    encoder_elevation_rad: NDArray[np.float64], *, max_latency_s: float = MAX_LATENCY_S,
) -> LatencyEstimate:
    """The delay of the IMU's elevation behind the mannequin encoder's, in [0, ``max_latency_s``].

    Raises
    ------
    FitError
        When the arm hardly moved (the latency is not observable) or the arrays do not match.
    """
    t = np.asarray(time_s, dtype=np.float64)
    imu = np.asarray(imu_elevation_rad, dtype=np.float64)
    encoder = np.asarray(encoder_elevation_rad, dtype=np.float64)
    if not (t.shape == imu.shape == encoder.shape) or t.size < 50:
        raise FitError("the latency segment needs at least 50 samples of time, IMU and encoder elevation")
    if not (np.isfinite(t).all() and np.isfinite(imu).all() and np.isfinite(encoder).all()):
        raise FitError("the latency segment has non-finite samples")
    if np.ptp(encoder) < MIN_EXCURSION_RAD:
        raise FitError(f"the arm moved {math.degrees(np.ptp(encoder)):.1f}° in the latency segment; "
                       f"at least {math.degrees(MIN_EXCURSION_RAD):.0f}° are needed to see the IMU's delay")
    inside = t >= t[0] + max_latency_s
    delays = np.arange(0.0, max_latency_s + GRID_S / 2, GRID_S)
    costs = np.array([_cost(t, imu, encoder, d, inside)[0] for d in delays])
    best = int(np.argmin(costs))
    latency = float(delays[best])
    if 0 < best < delays.size - 1:
        left, mid, right = costs[best - 1], costs[best], costs[best + 1]
        curvature = left - 2.0 * mid + right
        if curvature > 0.0:
            latency += 0.5 * GRID_S * (left - right) / curvature
    variance, offset = _cost(t, imu, encoder, latency, inside)
    return LatencyEstimate(latency_s=min(max(latency, 0.0), max_latency_s),
                           residual_rms_rad=math.sqrt(variance), offset_rad=offset)


LATENCY_COLUMNS = ("time_s", "elevation_rad", "mannequin_elevation_rad")


def read_latency_segment(path: str, flag: str = "--latency-recording") -> LatencyEstimate:
    """Identify the latency from a recording of the latency segment (CSV or Parquet with the columns
    :data:`LATENCY_COLUMNS`); a bad file is a :class:`FitError` naming ``flag`` and the problem."""
    import pandas as pd

    try:
        frame = pd.read_parquet(path) if str(path).endswith((".parquet", ".pq")) else pd.read_csv(path)
    except (OSError, ValueError) as error:
        raise FitError(f"{flag} {path}: cannot be read ({error})") from None
    missing = [name for name in LATENCY_COLUMNS if name not in frame.columns]
    if missing:
        raise FitError(f"{flag} {path}: missing column(s) {', '.join(missing)} "
                       f"(the latency segment needs {', '.join(LATENCY_COLUMNS)})")
    try:
        columns = [frame[name].to_numpy(dtype=np.float64) for name in LATENCY_COLUMNS]
    except (TypeError, ValueError):
        raise FitError(f"{flag} {path}: the columns {', '.join(LATENCY_COLUMNS)} must be numbers") from None
    try:
        return identify_imu_latency(*columns)
    except FitError as error:
        raise FitError(f"{flag} {path}: {error}") from None
