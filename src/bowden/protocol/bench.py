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
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, TypeVar, overload

import numpy as np
from numpy.typing import NDArray

from bowden.errors import ParameterError
from bowden.protocol.minimum_jerk import MinimumJerkCycle

# A time or an array of times: LatencyChirp's formula serves both.
_Time = TypeVar("_Time", float, NDArray[np.float64])


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


@dataclass(frozen=True, kw_only=True)
class LatencyChirp:
    """Segment 2 of the bench protocol (docs/identification.md, "The protocol, exactly"): the
    mannequin's motor moves the arm in position mode along a linear chirp about ``centre_rad`` of
    ±``amplitude_rad``, from ``start_hz`` to ``end_hz`` over ``duration_s``, faded in and out over the
    first and last second, while the TDU holds ``holding_torque_nm`` (the cable stays taut).

    The one definition of the chirp: ``bowden bench run`` drives it over the wire (``--chirp-s`` sets
    ``duration_s``) and the batch bench (:func:`bowden.sim.bench_latency.run_latency_segment`, at its
    own logging rate) simulates it.
    """

    centre_rad: float = math.radians(60.0)
    amplitude_rad: float = math.radians(15.0)
    start_hz: float = 0.3
    end_hz: float = 2.0
    duration_s: float = 12.0
    holding_torque_nm: float = 0.5

    def __post_init__(self) -> None:
        # Users reach the duration through --chirp-s alone; the other fields are the protocol's.
        if not 2.0 <= self.duration_s <= 120.0:
            raise ParameterError(
                f"--chirp-s must be in [2, 120] s (the latency chirp's duration), got {self.duration_s:g}"
            )
        low, high = self.centre_rad - self.amplitude_rad, self.centre_rad + self.amplitude_rad
        if not 0.0 < low < high < math.radians(115.0):
            raise ParameterError(f"the latency chirp must stay within 0°–115°, got "
                                 f"{math.degrees(low):g}°–{math.degrees(high):g}°")
        if not 0.05 <= self.start_hz < self.end_hz <= 5.0:
            raise ParameterError(f"the latency chirp's frequencies must rise within 0.05–5 Hz, got "
                                 f"{self.start_hz:g} → {self.end_hz:g} Hz")
        if not 0.05 <= self.holding_torque_nm <= 2.0:
            raise ParameterError(f"the latency chirp's holding torque must be in [0.05, 2] Nm, got "
                                 f"{self.holding_torque_nm:g}")

    @overload
    def elevation(self, time_s: float) -> tuple[float, float]: ...

    @overload
    def elevation(
        self, time_s: NDArray[np.floating[Any]]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...

    def elevation(
        self, time_s: float | NDArray[np.floating[Any]]
    ) -> tuple[float, float] | tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Elevation (rad) and its velocity (rad/s) at ``time_s`` from the chirp's start; at rest at the
        centre before it and after it. Floats for a time (the wire bench's cycle: plain ``math``, under a
        microsecond), arrays for an array of times (the batch bench's substeps)."""
        d = self.duration_s
        if isinstance(time_s, np.ndarray):
            t = np.clip(time_s.astype(np.float64), 0.0, d)
            fade = np.minimum(np.minimum(t, d - t), 1.0)
            fade_rate = np.where(fade >= 1.0, 0.0, np.where(t < 1.0, 1.0, -1.0))
            return self._along(t, fade, fade_rate, np.sin, np.cos)
        t_s = min(max(float(time_s), 0.0), d)
        fade_s = min(t_s, d - t_s, 1.0)
        fade_rate_s = 0.0 if fade_s >= 1.0 else (1.0 if t_s < 1.0 else -1.0)
        return self._along(t_s, fade_s, fade_rate_s, math.sin, math.cos)

    def _along(self, t: _Time, fade: _Time, fade_rate: _Time, sin: Callable[[_Time], _Time],
               cos: Callable[[_Time], _Time]) -> tuple[_Time, _Time]:
        """The chirp's one formula, for floats or arrays alike: ``t`` within [0, duration], ``fade`` the
        fade-in/out factor (0 to 1) and ``fade_rate`` its derivative (1/s)."""
        rate = (self.end_hz - self.start_hz) / self.duration_s
        phase = 2.0 * math.pi * (self.start_hz * t + 0.5 * rate * t * t)
        omega = 2.0 * math.pi * (self.start_hz + rate * t)
        theta = self.centre_rad + self.amplitude_rad * fade * sin(phase)
        theta_d = self.amplitude_rad * (fade_rate * sin(phase) + fade * omega * cos(phase))
        return theta, theta_d


@dataclass(frozen=True)
class StudyBlock:
    """One block of the study-like segment: its number (from 0), the controller's support and
    compensation, the study speed (``"V1"``…), all repetitions of the cycle at that speed; ``fit``
    if it belongs to a fit's blocks (:class:`StudyFit`), and then ``candidate``, the grid index of the
    dynamic compensation it runs (−1: the model as given, e.g. the paper's lines)."""

    index: int
    support: float | str
    speed: str
    compensation: str
    fit: bool = False
    candidate: int = -1


@dataclass(frozen=True, kw_only=True)
class StudyStrokes:
    """Segment 3 of the bench protocol: the study's minimum-jerk cycle (20° → 100° → 20° at the V1–V3
    peak speeds) driven by the mannequin's motor in impedance mode (MIT mode about the reference:
    ``stiffness_nm_rad``, ``damping_nms_rad``, the mannequin arm's inertia and the support law's
    nominal torque fed forward, with a wearer's motor noise, :class:`MotorNoise`) while the TDU runs
    the controller at ``controller_rate_hz`` with one compensation. For each support, each speed,
    each compensation in turn: ``rest_s`` at rest at the low end, then ``repetitions`` cycles. The
    same numbers as the batch bench's :mod:`bowden.sim.bench_study`.

    Parameters
    ----------
    supports
        The controller's supports: ``"pretension"`` or fractions.
    speeds
        Study speeds (``contracts.SPEEDS``).
    compensations
        Run in this order on the same strokes.
    repetitions
        Cycles per block (the first is not judged).
    hand_load_kg, subject_height_m, subject_mass_kg, subject_sex
        The wearer the controller is built for (its support law), and the load in the hand.
    """

    supports: tuple[float | str, ...] = ("pretension", 0.25, 0.5)
    speeds: tuple[str, ...] = ("V1", "V2", "V3")
    compensations: tuple[str, ...] = ("paper", "dynamic")
    repetitions: int = 7
    rest_s: float = 1.0
    low_rad: float = math.radians(20.0)
    high_rad: float = math.radians(100.0)
    stiffness_nm_rad: float = 25.0
    damping_nms_rad: float = 2.5
    hand_load_kg: float = 0.5
    controller_rate_hz: float = 500.0
    # The wearer the controller is built for: the simulated cohort's first participant (rounded), the
    # batch segment's mannequin.
    subject_height_m: float = 1.64
    subject_mass_kg: float = 49.4
    subject_sex: str = "female"
    # A wearer's motor noise on the mannequin's torque (:class:`MotorNoise`): its constant part (Nm),
    # the part growing with the feed-forward torque, its correlation time (s).
    motor_noise_nm: float = 0.5
    motor_noise_fraction: float = 0.01
    motor_noise_time_s: float = 0.25

    def __post_init__(self) -> None:
        from bowden.contracts import SPEEDS

        if not self.supports or not all(s == "pretension" or (isinstance(s, float | int) and 0.0 < s <= 1.0)
                                        for s in self.supports):
            raise ParameterError("the study-like segment's supports must be 'pretension' or in (0, 1]")
        if not self.speeds or any(speed not in SPEEDS for speed in self.speeds):
            raise ParameterError(f"the study-like segment's speeds must be among {', '.join(SPEEDS)}")
        if not self.compensations or any(name not in ("paper", "dynamic") for name in self.compensations):
            raise ParameterError("the study-like segment's compensations must be 'paper' and/or 'dynamic'")
        if not 2 <= self.repetitions <= 50:
            raise ParameterError(f"the study-like segment needs 2-50 repetitions, got {self.repetitions}")
        if not (0.0 < self.low_rad < self.high_rad < math.pi and 0.2 <= self.rest_s <= 10.0):
            raise ParameterError("StudyStrokes needs 0 < low_rad < high_rad < 180° and rest_s in [0.2, 10] s")
        if not (0.0 <= self.motor_noise_nm <= 5.0 and 0.0 <= self.motor_noise_fraction <= 0.2
                and 0.01 <= self.motor_noise_time_s <= 5.0):
            raise ParameterError("the mannequin's motor noise needs 0–5 Nm, a fraction of 0–0.2 and a "
                                 "correlation time of 0.01–5 s")
        if not (0.0 < self.stiffness_nm_rad <= 500.0 and 0.0 <= self.damping_nms_rad <= 5.0):
            raise ParameterError("the mannequin's gains must be within the AK80-9's MIT ranges: "
                                 "kp 0–500, kd 0–5")

    def blocks(self) -> list[StudyBlock]:
        """Every block in the order run: for each support, each speed, each compensation."""
        return [StudyBlock(index=i, support=support, speed=speed, compensation=name)
                for i, (support, speed, name) in enumerate(
                    (s, v, n) for s in self.supports for v in self.speeds for n in self.compensations)]

    def cycle(self, speed: str) -> MinimumJerkCycle:
        """The minimum-jerk cycle of ``speed``."""
        from bowden.contracts import SPEED_PEAK_DEG_S

        return MinimumJerkCycle(low_rad=self.low_rad, high_rad=self.high_rad,
                                peak_speed_rad_s=math.radians(SPEED_PEAK_DEG_S[speed]))

    def block_duration_s(self, speed: str) -> float:
        """How long a block at ``speed`` is recorded: the rest, the cycles, half a second after."""
        return self.rest_s + self.repetitions * self.cycle(speed).period_s + 0.5


@dataclass(frozen=True, kw_only=True)
class StudyFit:
    """The study-like fit on a bench (``bowden bench validate --fit``), run before the study-like
    strokes it is validated on: at ``support``, for each speed the paper's compensation once, then the
    dynamic compensation of each of ``candidates`` in turn, ``repetitions`` cycles each (the first is
    not judged); the strokes otherwise as :class:`StudyStrokes`'. The mannequin's motor noise of a fit
    block depends only on the support and speed (every candidate meets the same) and differs from the
    study-like blocks' (the validation's strokes are held out of the fit).

    Parameters
    ----------
    grid
        Every candidate of the fit, in its order: (drag scale, inertia scale, lowering-line shift Nm)
        (:func:`bowden.identify.study_fit.fit_grid`; kept in the journal, so a resume with another grid
        is refused).
    candidates
        The indices into ``grid`` run (all of it by default).
    """

    grid: tuple[tuple[float, float, float], ...]
    candidates: tuple[int, ...] = ()
    support: float | str = 0.5
    speeds: tuple[str, ...] = ("V1", "V2", "V3")
    repetitions: int = 4

    def __post_init__(self) -> None:
        if not self.grid:
            raise ParameterError("the study-like fit needs a grid of candidates")
        if not self.candidates:
            object.__setattr__(self, "candidates", tuple(range(len(self.grid))))
        if len(set(self.candidates)) != len(self.candidates) or not all(
                0 <= index < len(self.grid) for index in self.candidates):
            raise ParameterError(f"the study-like fit's candidates must be distinct indices into its "
                                 f"grid of {len(self.grid)}, got {self.candidates}")
        StudyStrokes(supports=(self.support,), speeds=self.speeds, repetitions=self.repetitions)

    def strokes(self, base: StudyStrokes | None = None) -> StudyStrokes:
        """The strokes the fit's blocks run: ``base``'s (the mannequin, the wearer, the rest) at the
        fit's support, speeds and repetitions."""
        return replace(base or StudyStrokes(), supports=(self.support,), speeds=self.speeds,
                       repetitions=self.repetitions)

    def blocks(self) -> list[StudyBlock]:
        """Every block in the order run: for each speed, the paper's once, then each candidate."""
        order = [(speed, name, candidate) for speed in self.speeds
                 for name, candidate in (("paper", -1), *(("dynamic", k) for k in self.candidates))]
        return [StudyBlock(index=i, support=self.support, speed=speed, compensation=name, fit=True,
                           candidate=candidate) for i, (speed, name, candidate) in enumerate(order)]

    def describe(self, candidate: int) -> str:
        """One candidate in words: ``drag ×1.4, inertia ×2, lowering line −0.05 Nm``."""
        drag, inertia, shift = self.grid[candidate]
        return f"drag ×{drag:g}, inertia ×{inertia:g}, lowering line {shift:+g} Nm"


class MotorNoise:
    """A wearer's motor noise for the mannequin's torque in one study-like block, one loop period
    at a time: (``motor_noise_nm`` + ``motor_noise_fraction`` · |feed-forward|) · z, z a unit
    Ornstein–Uhlenbeck process with correlation time ``motor_noise_time_s`` — the simulated cohort's
    mean (signal-dependent noise, Harris & Wolpert 1998, Nature 394:780; the batch bench's
    mannequin, :mod:`bowden.sim.bench_study`).

    A noise-free mannequin creeps through the slow turn held back by the stuck cable, as no wearer
    does, and the bench then judged a spike the study does not see (docs/dynamic_compensation.md, "A
    noise-free mannequin is not a wearer at the slow turn"). The draws depend only on the block's
    support and speed, and whether it is a fit's (:class:`StudyFit`), so each compensation — and each
    candidate of a fit — meets the same noise: the strokes stay paired.
    """

    def __init__(self, strokes: StudyStrokes, block: StudyBlock, period_s: float) -> None:
        from bowden.contracts import SPEEDS

        # Seeded by the support's value, not its place in the list: `bench validate --support 0.5`
        # meets the noise `bench run`'s 50 % blocks met.
        percent = 0 if block.support == "pretension" else round(100 * float(block.support))
        # A fit's blocks draw their own noise (held out of the validation's, as the batch fit's seed
        # is); every candidate of the fit meets the same.
        seed = [28, percent, SPEEDS.index(block.speed)] + ([1] if block.fit else [])
        self._rng = np.random.default_rng(seed)
        self._decay = math.exp(-period_s / strokes.motor_noise_time_s)
        self._spread = math.sqrt(1.0 - self._decay * self._decay)
        self._constant_nm = strokes.motor_noise_nm
        self._fraction = strokes.motor_noise_fraction
        self._state = 0.0

    def torque_nm(self, feedforward_nm: float) -> float:
        """The noise torque of the next loop period (> 0 raises, as the feed-forward)."""
        self._state = self._decay * self._state + self._spread * float(self._rng.standard_normal())
        return (self._constant_nm + self._fraction * abs(feedforward_nm)) * self._state
