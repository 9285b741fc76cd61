"""The latency segment on the simulated bench: the mannequin moves the arm along a chirp.

The mannequin's motor holds the arm in position mode on a chirp about ``centre`` (docs/identification.md,
"Latency segment") while the tendon driver holds a constant low torque (the cable stays taut, as the
suit is worn on the bench). Logged: the mannequin's joint encoder (read in the same cycle) and the IMU
(its latency, noise and bias), at the protocol's rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from bowden.errors import ParameterError
from bowden.sim import _kernels as k
from bowden.sim.parameters import ArmParameters, SuitParameters, check_seed
from bowden.sim.plant import Plant

ENCODER_ELEVATION = "mannequin_elevation_rad"
IMU_ELEVATION = "elevation_rad"
TIME = "time_s"


@dataclass(frozen=True, kw_only=True)
class LatencySegment:
    """The chirp: centre and amplitude (rad), start and end frequency (Hz), duration (s), the driver's
    holding torque (Nm) and the logging rate (Hz)."""

    centre_rad: float = math.radians(60.0)
    amplitude_rad: float = math.radians(15.0)
    start_hz: float = 0.3
    end_hz: float = 2.0
    duration_s: float = 12.0
    holding_torque_nm: float = 0.5
    sample_rate_hz: float = 200.0

    def __post_init__(self) -> None:
        low, high = self.centre_rad - self.amplitude_rad, self.centre_rad + self.amplitude_rad
        if not 0.0 < low < high < math.radians(115.0):
            raise ParameterError("LatencySegment: the chirp must stay within 0°–115°")
        if not 0.05 <= self.start_hz < self.end_hz <= 5.0:
            raise ParameterError("LatencySegment: frequencies must rise within 0.05–5 Hz")
        if not 2.0 <= self.duration_s <= 120.0:
            raise ParameterError("LatencySegment.duration_s must be in [2, 120] s")

    def elevation(self, time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Elevation and its velocity along the linear chirp, faded in and out over its first and last
        second (so it starts and ends at rest at the centre)."""
        rate = (self.end_hz - self.start_hz) / self.duration_s
        phase = 2.0 * math.pi * (self.start_hz * time_s + 0.5 * rate * time_s**2)
        omega = 2.0 * math.pi * (self.start_hz + rate * time_s)
        fade = np.clip(np.minimum(time_s, self.duration_s - time_s), 0.0, 1.0)
        fade_d = np.where(time_s < 1.0, 1.0, np.where(time_s > self.duration_s - 1.0, -1.0, 0.0))
        fade_d = np.where(fade >= 1.0, 0.0, fade_d)
        theta = self.centre_rad + self.amplitude_rad * fade * np.sin(phase)
        theta_d = self.amplitude_rad * (fade_d * np.sin(phase) + fade * omega * np.cos(phase))
        return theta, theta_d


def run_latency_segment(
    suit: SuitParameters | None = None, segment: LatencySegment | None = None, *, seed: int = 0,
) -> pd.DataFrame:
    """The latency segment on the simulated bench: ``time_s``, the IMU's ``elevation_rad`` and the
    mannequin encoder's ``mannequin_elevation_rad``."""
    check_seed(seed)
    suit = suit if suit is not None else SuitParameters()
    segment = segment if segment is not None else LatencySegment()
    rng = np.random.default_rng(seed)
    plant = Plant(suit, ArmParameters(), elevation_rad=segment.centre_rad, tension_n=10.0)
    dt = suit.substep_s
    steps = np.arange(1, round(segment.duration_s / dt) + 1) * dt
    theta, theta_d = segment.elevation(steps)
    command = np.array([segment.holding_torque_nm, 0.0, 0.0, 0.0, 0.0])
    record = plant.integrate(steps.size, motor_mode=k.MOTOR_TORQUE, command=command,
                             arm_mode=k.ARM_PRESCRIBED, arm_a=theta, arm_b=theta_d)
    every = max(1, round(1.0 / (segment.sample_rate_hz * dt)))
    logged = np.arange(every - 1, steps.size, every)
    times = steps[logged]
    imu = suit.imu
    # The IMU's sample logged at t is the arm's elevation at t − latency (the arm rests before t = 0).
    late = np.interp(times - imu.latency_s, steps, record[:, k.R_TH], left=segment.centre_rad)
    noise = imu.elevation_noise_rad * rng.standard_normal(times.size)
    return pd.DataFrame({
        TIME: times,
        IMU_ELEVATION: late + imu.elevation_bias_rad + noise,
        ENCODER_ELEVATION: record[logged, k.R_TH],
    })
