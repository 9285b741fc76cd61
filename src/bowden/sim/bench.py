"""The mannequin bench: the paper's identification protocol on the simulated suit.

Paper, "Data acquisition": the tendon driver unit is controlled in trajectory at quasi-constant spool
velocities (±0.5, 1, 2, 3, 4, 5, 6 rad/s) across the arm's range (20°–110°), five repetitions each,
while the mannequin's motor applies constant loads (0.5, 1, 2, 3, 4 Nm) in torque control. Here each
stroke raises the arm from 20° to 110° at +v, holds, and lowers it back at −v; the recording holds
what the real bench logs — the motor's reported torque and encoder velocity, the load cell and the
IMU, with their noise — in the bench-recording contract (``bowden.contracts.BENCH_*``) with one
``trial`` number per stroke.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from bowden import contracts as c
from bowden.errors import ParameterError
from bowden.sim import _kernels as k
from bowden.sim.parameters import ArmParameters, SuitParameters, check_seed
from bowden.sim.plant import Plant

_RAMP_CHUNK_S = 0.005  # the host updates the spool's velocity target every 5 ms during ramps


@dataclass(frozen=True, kw_only=True)
class BenchProtocol:
    """The identification protocol (defaults: the paper's).

    Parameters
    ----------
    spool_speeds_rad_s
        Spool speeds, each run raising (+) and lowering (−).
    loads_nm
        Mannequin load torques (pull the arm down).
    repetitions
        Repetitions of each speed and load.
    low_rad, high_rad
        Range of each stroke.
    hold_s
        Rest at each end of a stroke.
    sample_rate_hz
        Logging rate of the recording.
    spool_acceleration_rad_s2
        Acceleration of the trapezoidal spool-velocity profile at the ends of each stroke.
    position_gain_nm_rad, velocity_gain_nms_rad
        The motor's trajectory-tracking gains (MIT-mode kp, kd; AK60-6 allows 0–500 and 0–5).
    mannequin
        The mannequin's arm.
    """

    spool_speeds_rad_s: tuple[float, ...] = (0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
    loads_nm: tuple[float, ...] = (0.5, 1.0, 2.0, 3.0, 4.0)
    repetitions: int = 5
    low_rad: float = math.radians(20.0)
    high_rad: float = math.radians(110.0)
    hold_s: float = 0.3
    sample_rate_hz: float = 200.0
    spool_acceleration_rad_s2: float = 30.0
    position_gain_nm_rad: float = 30.0
    velocity_gain_nms_rad: float = 0.6
    mannequin: ArmParameters = field(default_factory=ArmParameters)

    def __post_init__(self) -> None:
        if not self.spool_speeds_rad_s or not all(0.05 <= v <= 30.0 for v in self.spool_speeds_rad_s):
            raise ParameterError("BenchProtocol.spool_speeds_rad_s must be speeds in [0.05, 30] rad/s")
        if not self.loads_nm or not all(0.05 <= t <= 20.0 for t in self.loads_nm):
            raise ParameterError("BenchProtocol.loads_nm must be load torques in [0.05, 20] Nm")
        if not 1 <= self.repetitions <= 50:
            raise ParameterError(f"BenchProtocol.repetitions must be in [1, 50], got {self.repetitions}")
        if not (0.0 < self.low_rad < self.high_rad < self.mannequin.max_elevation_rad):
            raise ParameterError(
                "BenchProtocol needs 0 < low_rad < high_rad < the mannequin's max elevation"
            )
        if not 0.0 <= self.hold_s <= 5.0:
            raise ParameterError(f"BenchProtocol.hold_s must be in [0, 5] s, got {self.hold_s}")
        if not 20.0 <= self.sample_rate_hz <= 2000.0:
            raise ParameterError(
                f"BenchProtocol.sample_rate_hz must be in [20, 2000], got {self.sample_rate_hz}"
            )
        if not 1.0 <= self.spool_acceleration_rad_s2 <= 1000.0:
            raise ParameterError("BenchProtocol.spool_acceleration_rad_s2 must be in [1, 1000] rad/s²")
        if not (0.0 <= self.position_gain_nm_rad <= 500.0 and 0.0 <= self.velocity_gain_nms_rad <= 5.0):
            raise ParameterError("BenchProtocol gains must be within the AK60-6 MIT ranges: kp 0–500, kd 0–5")

    @property
    def n_strokes(self) -> int:
        return 2 * len(self.spool_speeds_rad_s) * len(self.loads_nm) * self.repetitions


class _Bench:
    """State of a bench run: the plant, the recording under construction and the sensor noise."""

    def __init__(self, suit: SuitParameters, protocol: BenchProtocol, seed: int) -> None:
        self.suit = suit
        self.protocol = protocol
        self.rng = np.random.default_rng(seed)
        self.plant = Plant(suit, protocol.mannequin, elevation_rad=protocol.low_rad, tension_n=5.0)
        self.every = max(1, round(1.0 / (protocol.sample_rate_hz * suit.substep_s)))
        self.parts: list[NDArray[np.float64]] = []
        self.trial = 0

    def run(
        self, n_steps: int, command: NDArray[np.float64], load_nm: float, stop_direction: int = 0,
        stop_rad: float = 0.0,
    ) -> NDArray[np.float64]:
        """Integrate in trajectory mode; keeps the logged samples and returns the full record."""
        arm = np.full(n_steps, -load_nm)
        first_step = self.plant.steps_done
        record = self.plant.integrate(
            n_steps, motor_mode=k.MOTOR_TRAJECTORY, command=command, arm_mode=k.ARM_TORQUE,
            arm_a=arm, arm_b=np.zeros(n_steps), stop_direction=stop_direction, stop_elevation_rad=stop_rad,
        )
        steps = first_step + 1 + np.arange(record.shape[0])
        logged = steps % self.every == 0
        if np.any(logged):
            self.parts.append(self._log(steps[logged] * self.suit.substep_s, record[logged]))
        return record

    def _log(self, times: NDArray[np.float64], rows: NDArray[np.float64]) -> NDArray[np.float64]:
        imu, cell, ratio = self.suit.imu, self.suit.load_cell, self.suit.motor.torque_constant_ratio
        n = times.size
        out = np.empty((n, 6))
        out[:, 0] = times
        out[:, 1] = rows[:, k.R_MOTOR_TAU] / ratio  # the driver's estimate from current
        out[:, 2] = rows[:, k.R_SPOOL_W]
        out[:, 3] = rows[:, k.R_T_OUT] + cell.offset_n + cell.noise_n * self.rng.standard_normal(n)
        noise = imu.elevation_noise_rad * self.rng.standard_normal(n)
        out[:, 4] = rows[:, k.R_TH] + imu.elevation_bias_rad + noise
        out[:, 5] = self.trial
        return out

    def hold(self, load_nm: float) -> None:
        q = float(self.plant.state_vector[k.X_SPOOL_Q])
        p = self.protocol
        command = np.array([q, 0.0, p.position_gain_nm_rad, p.velocity_gain_nms_rad, 0.0])
        self.run(max(1, round(self.protocol.hold_s / self.suit.substep_s)), command, load_nm)

    def stroke(self, velocity: float, load_nm: float, stop_rad: float) -> None:
        """Move the spool at ``velocity`` (trapezoidal profile) so that the arm stops near ``stop_rad``."""
        p = self.protocol
        dt = self.suit.substep_s
        q = float(self.plant.state_vector[k.X_SPOOL_Q])
        command = np.array([q, 0.0, p.position_gain_nm_rad, p.velocity_gain_nms_rad, 0.0])
        direction = 1 if velocity > 0 else -1
        ramp_s = abs(velocity) / p.spool_acceleration_rad_s2
        ramp_chunks = max(1, math.ceil(ramp_s / _RAMP_CHUNK_S))
        chunk_steps = max(1, round(ramp_s / ramp_chunks / dt))
        for i in range(1, ramp_chunks + 1):
            command[1] = velocity * i / ramp_chunks
            self.run(chunk_steps, command, load_nm)
        # Brake where the spool's stopping distance, seen at the arm, ends the stroke at stop_rad.
        vec = self.plant.vector
        radius = self.suit.motor.spool_radius_m
        braking_cable_m = radius * velocity * velocity / (2.0 * p.spool_acceleration_rad_s2)
        brake_rad = stop_rad - direction * braking_cable_m / float(k.moment_arm_m(vec, stop_rad))
        travel = abs(float(k.path_length_m(vec, p.low_rad) - k.path_length_m(vec, p.high_rad)))
        limit_s = 3.0 * travel / (self.suit.motor.spool_radius_m * abs(velocity)) + 2.0
        self.run(round(limit_s / dt), command, load_nm, direction, brake_rad)
        for i in range(ramp_chunks - 1, -1, -1):
            command[1] = velocity * i / ramp_chunks
            self.run(chunk_steps, command, load_nm)
        self.trial += 1


def run_bench(
    suit: SuitParameters | None = None,
    protocol: BenchProtocol | None = None,
    *,
    seed: int = 0,
    progress: Callable[[int, int], None] | Literal[False] = False,
) -> pd.DataFrame:
    """Run the identification protocol on the simulated mannequin bench.

    Returns
    -------
    DataFrame with the bench-recording columns (``contracts.BENCH_COLUMNS``) and ``trial`` (one
    number per stroke; holds belong to the stroke that follows them).
    """
    check_seed(seed)
    suit = suit if suit is not None else SuitParameters()
    protocol = protocol if protocol is not None else BenchProtocol()
    bench = _Bench(suit, protocol, seed)
    done = 0
    for load in protocol.loads_nm:
        for speed in protocol.spool_speeds_rad_s:
            for _ in range(protocol.repetitions):
                bench.hold(load)
                bench.stroke(speed, load, protocol.high_rad)
                bench.hold(load)
                bench.stroke(-speed, load, protocol.low_rad)
                done += 2
                if progress:
                    progress(done, protocol.n_strokes)
    data = np.concatenate(bench.parts)
    frame = pd.DataFrame(
        {
            c.BENCH_TIME: data[:, 0],
            c.BENCH_MOTOR_TORQUE: data[:, 1],
            c.BENCH_MOTOR_VELOCITY: data[:, 2],
            c.BENCH_TENSION: data[:, 3],
            c.BENCH_ELEVATION: data[:, 4],
            c.BENCH_TRIAL: data[:, 5].astype(np.int64),
        }
    )
    return frame
