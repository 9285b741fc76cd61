"""The mannequin bench: the paper's identification protocol on the simulated suit.

Paper, "Data acquisition": the tendon driver unit is controlled in trajectory at quasi-constant spool
velocities (±0.5, 1, 2, 3, 4, 5, 6 rad/s) across the arm's range (20°–110°), five repetitions each,
while the mannequin's motor applies constant loads (0.5, 1, 2, 3, 4 Nm) in torque control. Here each
stroke raises the arm from 20° to 110° at +v, holds, and lowers it back at −v; the recording holds
what the real bench logs — the motor's reported torque and encoder velocity, the load cell and the
IMU, with their noise — in the bench-recording contract (``bowden.contracts.BENCH_*``) with one
``trial`` number per stroke. The protocol's numbers are :class:`bowden.protocol.bench.BenchProtocol`
(re-exported here).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Literal

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from bowden import contracts as c
from bowden.errors import ParameterError
from bowden.protocol.bench import BenchProtocol

__all__ = ["BenchProtocol", "run_bench"]
from bowden.sim import _kernels as k
from bowden.sim.parameters import ArmParameters, SuitParameters, check_seed
from bowden.sim.plant import Plant

_RAMP_CHUNK_S = 0.005  # the host updates the spool's velocity target every 5 ms during ramps


class _Bench:
    """State of a bench run: the plant, the recording under construction and the sensor noise."""

    def __init__(self, suit: SuitParameters, protocol: BenchProtocol, mannequin: ArmParameters,
                 seed: int) -> None:
        self.suit = suit
        self.protocol = protocol
        self.rng = np.random.default_rng(seed)
        self.plant = Plant(suit, mannequin, elevation_rad=protocol.low_rad, tension_n=5.0)
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
        imu, cell = self.suit.imu, self.suit.load_cell
        n = times.size
        out = np.empty((n, 6))
        out[:, 0] = times
        out[:, 1] = rows[:, k.R_REPORTED_TAU]  # the driver's estimate from current
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
    mannequin: ArmParameters | None = None,
) -> pd.DataFrame:
    """Run the identification protocol (:class:`~bowden.protocol.bench.BenchProtocol`) on the
    simulated mannequin bench, whose arm is ``mannequin`` (default :class:`ArmParameters`).

    Returns
    -------
    DataFrame with the bench-recording columns (``contracts.BENCH_COLUMNS``) and ``trial`` (one
    number per stroke; holds belong to the stroke that follows them).
    """
    check_seed(seed)
    suit = suit if suit is not None else SuitParameters()
    protocol = protocol if protocol is not None else BenchProtocol()
    mannequin = mannequin if mannequin is not None else ArmParameters()
    if protocol.high_rad >= mannequin.max_elevation_rad:
        raise ParameterError("BenchProtocol.high_rad must lie below the mannequin's max elevation "
                             f"({math.degrees(mannequin.max_elevation_rad):.0f}°)")
    bench = _Bench(suit, protocol, mannequin, seed)
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
