"""Elevation, velocity and acceleration of the arm from the IMU, predicted across its latency.

A Kalman filter at the controller's fixed rate on the state (θ, θ̇, θ̈, b): elevation, its velocity
and acceleration under a white-jerk model, and the gyroscope's bias b (a slow random walk). The IMU
gives the elevation θ (from its orientation) and the gyroscope's rate θ̇ + b. Because the rate is
fixed and the model linear, the gain converges to a constant: it is solved once (discrete algebraic
Riccati equation) and each update is a few plain-float multiply-adds. The bias is observable from the
elevation itself, so it is learnt whenever the arm holds still and whenever it moves.

Samples arrive ``latency`` seconds old (orientation filter and radio link); the estimate is carried
forward across it with the filter's own velocity and acceleration, which is what lets the
compensation see a turn when it happens rather than a latency later.

The filter runs inside the controller's step (:mod:`bowden.control.step`), the one place its update
is written; ``tests/control/test_dynamic_step.py`` checks it against the filter in matrix form.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bowden.errors import ParameterError

# Process noise of the white-jerk model, per step. Chosen on the default simulated suit (only): 15 rad/s³
# follows the turns of 60–180 °/s movements as well as 55 did there, and keeps the predicted velocity's
# noise at rest at ≈ 0.01 rad/s (1 σ) with the NGIMU's gyro, a seventh of the reversal hysteresis;
# at 55 it was 0.018 rad/s and the command toggled between the lines at rest (tested).
DEFAULT_JERK_SD_RAD_S3 = 15.0
DEFAULT_ELEVATION_NOISE_RAD = math.radians(0.3)
DEFAULT_GYRO_NOISE_RAD_S = math.radians(1.5)
DEFAULT_BIAS_WALK_RAD_S = 1e-5  # per step: a bias that drifts over minutes, not within a movement


@dataclass(frozen=True, kw_only=True)
class EstimatorGains:
    """Constant Kalman gain of the estimator, row by state (θ, θ̇, θ̈, b), columns (elevation, gyro)."""

    period_s: float
    latency_s: float
    gain: tuple[tuple[float, float], ...]


def estimator_gains(
    period_s: float,
    latency_s: float = 0.0,
    *,
    jerk_sd_rad_s3: float = DEFAULT_JERK_SD_RAD_S3,
    elevation_noise_rad: float = DEFAULT_ELEVATION_NOISE_RAD,
    gyro_noise_rad_s: float = DEFAULT_GYRO_NOISE_RAD_S,
    bias_walk_rad_s: float = DEFAULT_BIAS_WALK_RAD_S,
) -> EstimatorGains:
    """The steady-state gain for a filter run every ``period_s`` seconds."""
    for name, value, low in (
        ("period_s", period_s, 1e-5),
        ("jerk_sd_rad_s3", jerk_sd_rad_s3, 1e-6),
        ("elevation_noise_rad", elevation_noise_rad, 1e-9),
        ("gyro_noise_rad_s", gyro_noise_rad_s, 1e-9),
        ("bias_walk_rad_s", bias_walk_rad_s, 1e-12),
    ):
        if not (math.isfinite(value) and value >= low):
            raise ParameterError(f"{name} must be a finite number >= {low:g}, got {value!r}")
    if not (math.isfinite(latency_s) and 0.0 <= latency_s <= 0.2):
        raise ParameterError(f"latency_s must be in [0, 0.2] s, got {latency_s!r}")
    dt = period_s
    f = np.eye(4)
    f[0, 1], f[0, 2], f[1, 2] = dt, 0.5 * dt * dt, dt
    g = np.array([dt**3 / 6.0, 0.5 * dt * dt, dt, 0.0])
    q = jerk_sd_rad_s3**2 * np.outer(g, g)
    q[3, 3] = bias_walk_rad_s**2
    h = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 1.0]])
    r = np.diag([elevation_noise_rad**2, gyro_noise_rad_s**2])
    import scipy.linalg  # here, not at the top: `bowden run --help` need not import it (0.4 s)

    prior = scipy.linalg.solve_discrete_are(f.T, h.T, q, r)
    gain = prior @ h.T @ np.linalg.inv(h @ prior @ h.T + r)
    rows = tuple((float(row[0]), float(row[1])) for row in gain)
    return EstimatorGains(period_s=period_s, latency_s=latency_s, gain=rows)
