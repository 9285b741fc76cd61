"""The paper's identification protocol on the mannequin bench, as numbers (simulated or real bench).

Paper, "Data acquisition": the tendon driver unit is controlled in trajectory at quasi-constant spool
velocities (±0.5, 1, 2, 3, 4, 5, 6 rad/s) across the arm's range (20°–110°), five repetitions each,
while the mannequin's motor applies constant loads (0.5, 1, 2, 3, 4 Nm) in torque control. Each
stroke raises the arm across the range at +v, or lowers it at −v, after a hold; one stroke is one
``trial`` of the bench recording. :func:`bowden.sim.run_bench` runs it on the simulated bench,
``bowden bench run`` on a real (or the simulated) bench over the devices' wires.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bowden.errors import ParameterError


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

    def __post_init__(self) -> None:
        if not self.spool_speeds_rad_s or not all(0.05 <= v <= 30.0 for v in self.spool_speeds_rad_s):
            raise ParameterError("BenchProtocol.spool_speeds_rad_s must be speeds in [0.05, 30] rad/s")
        if not self.loads_nm or not all(0.05 <= t <= 20.0 for t in self.loads_nm):
            raise ParameterError("BenchProtocol.loads_nm must be load torques in [0.05, 20] Nm")
        if not 1 <= self.repetitions <= 50:
            raise ParameterError(f"BenchProtocol.repetitions must be in [1, 50], got {self.repetitions}")
        if not (0.0 < self.low_rad < self.high_rad < math.pi):
            raise ParameterError("BenchProtocol needs 0 < low_rad < high_rad < 180°")
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

    def strokes(self) -> list[BenchStroke]:
        """Every stroke in the order run: for each load, each speed, each repetition, up then down."""
        strokes: list[BenchStroke] = []
        for load in self.loads_nm:
            for speed in self.spool_speeds_rad_s:
                for repetition in range(self.repetitions):
                    for velocity in (speed, -speed):
                        strokes.append(BenchStroke(index=len(strokes), load_nm=load,
                                                   spool_velocity_rad_s=velocity, repetition=repetition))
        return strokes


@dataclass(frozen=True)
class BenchStroke:
    """One stroke of the protocol: its number (the recording's ``trial``), the mannequin's load, the
    spool velocity (> 0 raising) and which repetition of its speed and load it is (from 0)."""

    index: int
    load_nm: float
    spool_velocity_rad_s: float
    repetition: int

    @property
    def raising(self) -> bool:
        return self.spool_velocity_rad_s > 0.0


# A protocol a tenth the size of the paper's (2 loads × 4 speeds × 2 repetitions), for quick runs of
# the study and the sweep.
QUICK_BENCH = BenchProtocol(spool_speeds_rad_s=(0.5, 1.0, 3.0, 6.0), loads_nm=(1.0, 3.0), repetitions=2)
