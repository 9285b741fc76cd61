"""Bench recordings generated from the single-bend transmission law, with the truth known by hand.

The paper's protocol (section "Data acquisition"): the spool runs at quasi-constant velocities while
the mannequin arm holds a constant load torque; raising and lowering sweeps cover 20°–110°. Here the
arm's cable moment arm r(θ) grows linearly from 5 cm at 20° to 12 cm at 110° (docs/design.md), the
load cell reads T_out = load / r(θ), and the motor torque follows the law exactly:

    raising  (spool velocity > 0): τ = b_r + R·T_out·(1 + k)/(1 − k)
    lowering (spool velocity < 0): τ = b_l + R·T_out·(1 − k)/(1 + k)

so the identified lines must be m_r = R(1+k)/(1−k), m_l = R(1−k)/(1+k) and the intercepts b_r, b_l.
With R = 0.035 m and k = 0.1: m_r = 0.0427777…, m_l = 0.0286363….
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from bowden.contracts import (
    BENCH_ELEVATION,
    BENCH_MOTOR_TORQUE,
    BENCH_MOTOR_VELOCITY,
    BENCH_TENSION,
    BENCH_TIME,
    BENCH_TRIAL,
)

LOW_RAD = math.radians(20.0)
HIGH_RAD = math.radians(110.0)


@dataclass(frozen=True)
class LawTruth:
    k: float = 0.1
    pulley_radius_m: float = 0.035
    intercept_raising_nm: float = 0.06
    intercept_lowering_nm: float = -0.02

    @property
    def slope_raising_m(self) -> float:
        return self.pulley_radius_m * (1.0 + self.k) / (1.0 - self.k)

    @property
    def slope_lowering_m(self) -> float:
        return self.pulley_radius_m * (1.0 - self.k) / (1.0 + self.k)


def moment_arm_m(elevation_rad: Any) -> Any:
    """Linear 5 cm at 20° to 12 cm at 110° (floats or arrays)."""
    return 0.05 + 0.07 * (elevation_rad - LOW_RAD) / (HIGH_RAD - LOW_RAD)


def _sweep(
    speed_rad_s: float, rate_hz: float, truth: LawTruth, accel_rad_s2: float
) -> tuple[np.ndarray, ...]:
    """One raise from 20° to 110°, a pause, one lower back, a pause: spool velocity and elevation."""
    dt = 1.0 / rate_hz
    velocities: list[float] = []
    elevations: list[float] = []
    theta = LOW_RAD
    for sign, target in ((1.0, HIGH_RAD), (-1.0, LOW_RAD)):
        omega = 0.0
        # Accelerate, cruise, and brake so that the arm stops at the target (trapezoidal profile).
        while (target - theta) * sign > 0.0:
            arm_rate = truth.pulley_radius_m / moment_arm_m(theta)
            remaining_spool = abs(target - theta) / arm_rate
            braking = omega * omega / (2.0 * accel_rad_s2)
            if remaining_spool <= braking:
                omega = max(omega - accel_rad_s2 * dt, 0.02)
            else:
                omega = min(omega + accel_rad_s2 * dt, speed_rad_s)
            theta += sign * omega * arm_rate * dt
            velocities.append(sign * omega)
            elevations.append(theta)
        pause = int(0.5 * rate_hz)
        velocities.extend([0.0] * pause)
        elevations.extend([theta] * pause)
    return np.array(velocities), np.array(elevations)


def law_bench_frame(
    *,
    truth: LawTruth | None = None,
    spool_speeds_rad_s: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0, 6.0),
    loads_nm: tuple[float, ...] = (1.0, 3.0),
    repetitions: int = 1,
    rate_hz: float = 200.0,
    accel_rad_s2: float = 20.0,
    noise_tension_n: float = 0.0,
    noise_torque_nm: float = 0.0,
    outlier_fraction: float = 0.0,
    seed: int = 0,
) -> pd.DataFrame:
    """A bench recording (contract columns plus ``trial``): one trial per speed × load × repetition."""
    truth = truth or LawTruth()
    rng = np.random.default_rng(seed)
    frames = []
    trial = 0
    # The kinematics depend on the speed only: integrate each sweep once.
    sweeps = {speed: _sweep(speed, rate_hz, truth, accel_rad_s2) for speed in spool_speeds_rad_s}
    for _ in range(repetitions):
        for load in loads_nm:
            for speed in spool_speeds_rad_s:
                velocity, elevation = sweeps[speed]
                tension = load / moment_arm_m(elevation)
                sign = np.sign(velocity)
                ratio = np.where(sign > 0, (1 + truth.k) / (1 - truth.k), (1 - truth.k) / (1 + truth.k))
                ratio = np.where(sign == 0, 1.0, ratio)
                intercept = np.where(sign > 0, truth.intercept_raising_nm, truth.intercept_lowering_nm)
                intercept = np.where(sign == 0, 0.0, intercept)
                torque = intercept + truth.pulley_radius_m * ratio * tension
                n = velocity.size
                tension_measured = (
                    tension + rng.normal(0.0, noise_tension_n, n) if noise_tension_n else tension
                )
                torque_measured = torque + rng.normal(0.0, noise_torque_nm, n) if noise_torque_nm else torque
                if outlier_fraction:
                    bad = rng.random(n) < outlier_fraction
                    torque_measured = np.where(
                        bad, torque_measured + rng.uniform(0.3, 1.0, n), torque_measured
                    )
                frames.append(
                    pd.DataFrame(
                        {
                            BENCH_TIME: np.arange(n) / rate_hz,
                            BENCH_MOTOR_TORQUE: torque_measured,
                            BENCH_MOTOR_VELOCITY: velocity,
                            BENCH_TENSION: tension_measured,
                            BENCH_ELEVATION: elevation,
                            BENCH_TRIAL: trial,
                        }
                    )
                )
                trial += 1
    return pd.concat(frames, ignore_index=True)
