"""The latency segment on the simulated bench: the mannequin moves the arm along a chirp.

The mannequin's motor holds the arm in position mode on the protocol's chirp
(:class:`bowden.protocol.bench.LatencyChirp`, docs/identification.md, "Latency segment") while the
tendon driver holds a constant low torque (the cable stays taut, as the suit is worn on the bench).
Logged: the mannequin's joint encoder (read in the same cycle) and the IMU (its latency, noise and
bias), at the protocol's rate.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from bowden.protocol.bench import BenchProtocol, LatencyChirp
from bowden.sim import _kernels as k
from bowden.sim.parameters import ArmParameters, SuitParameters, check_seed
from bowden.sim.plant import Plant
from bowden.validation import check_number

ENCODER_ELEVATION = "mannequin_elevation_rad"
IMU_ELEVATION = "elevation_rad"
TIME = "time_s"
# The batch bench logs the segment at the bench protocol's recording rate (200 Hz), as `bowden bench run`
# writes <stem>.latency.csv, so identify --latency-recording reads the same kind of file.
SAMPLE_RATE_HZ: float = BenchProtocol.sample_rate_hz


def run_latency_segment(
    suit: SuitParameters | None = None, chirp: LatencyChirp | None = None, *, seed: int = 0,
    sample_rate_hz: float = SAMPLE_RATE_HZ,
) -> pd.DataFrame:
    """The latency segment on the simulated bench: ``time_s``, the IMU's ``elevation_rad`` and the
    mannequin encoder's ``mannequin_elevation_rad``.

    Parameters
    ----------
    suit
        The simulated suit (default :class:`SuitParameters`); its IMU's latency, noise and bias.
    chirp
        The protocol's chirp (default :class:`~bowden.protocol.bench.LatencyChirp`).
    seed
        The IMU noise's seed.
    sample_rate_hz
        The logging rate, at most the plant's substep rate.
    """
    check_seed(seed)
    suit = suit if suit is not None else SuitParameters()
    chirp = chirp if chirp is not None else LatencyChirp()
    dt = suit.substep_s
    check_number(sample_rate_hz, "the latency segment's sample rate (Hz)", 0.0, 1.0 / dt, low_open=True)
    rng = np.random.default_rng(seed)
    plant = Plant(suit, ArmParameters(), elevation_rad=chirp.centre_rad, tension_n=10.0)
    steps = np.arange(1, round(chirp.duration_s / dt) + 1) * dt
    theta, theta_d = chirp.elevation(steps)
    command = np.array([chirp.holding_torque_nm, 0.0, 0.0, 0.0, 0.0])
    record = plant.integrate(steps.size, motor_mode=k.MOTOR_TORQUE, command=command,
                             arm_mode=k.ARM_PRESCRIBED, arm_a=theta, arm_b=theta_d)
    every = max(1, round(1.0 / (sample_rate_hz * dt)))
    logged = np.arange(every - 1, steps.size, every)
    times = steps[logged]
    imu = suit.imu
    # The IMU's sample logged at t is the arm's elevation at t − latency (the arm rests before t = 0).
    late = np.interp(times - imu.latency_s, steps, record[:, k.R_TH], left=chirp.centre_rad)
    noise = imu.elevation_noise_rad * rng.standard_normal(times.size)
    return pd.DataFrame({
        TIME: times,
        IMU_ELEVATION: late + imu.elevation_bias_rad + noise,
        ENCODER_ELEVATION: record[logged, k.R_TH],
    })
