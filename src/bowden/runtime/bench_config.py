"""What a bench run is given and what it reports: the devices, the watchdogs, the configuration.

The run itself is :class:`bowden.runtime.bench.BenchRun`; these types are its contract (the CLI and
the tests build them).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Protocol

from bowden.errors import BowdenError, ParameterError
from bowden.hardware.protocols import Clock, ElevationSensor, MotorState, TensionSensor
from bowden.model import CompensationModel
from bowden.model.geometry import CuffGeometry
from bowden.protocol.bench import BenchProtocol, LatencyChirp, StudyBlock, StudyFit, StudyStrokes
from bowden.runtime.slack import SlackTakeUp


class BenchMotor(Protocol):
    """What the bench needs of an AK-series driver (:class:`bowden.hardware.ak60.AK60Motor`)."""

    last_state: MotorState | None
    unanswered_commands: int
    oldest_unanswered_send_s: float

    def enable(self) -> MotorState: ...

    def disable(self) -> None: ...

    def request_exit(self) -> None: ...

    def await_exit(self) -> bool: ...

    def command_torque(self, torque_nm: float) -> MotorState | None: ...

    def command_mit(self, position_rad: float, velocity_rad_s: float, kp: float, kd: float,
                    torque_nm: float = 0.0) -> MotorState | None: ...


class FitModels(Protocol):
    """What gives a study-like fit's blocks their models (the CLI's: :mod:`bowden.identify.study_fit`'s
    grid and choice, so that the bench and the batch fit share one definition)."""

    def candidate(self, model: CompensationModel, index: int) -> CompensationModel:
        """``model`` with the fit's candidate ``index`` applied."""
        ...

    def chosen(self, model: CompensationModel, study_recording: Path) -> CompensationModel:
        """The candidate the fit's blocks recorded in ``study_recording`` choose (the validation's
        model)."""
        ...


_SHARED_HOST_SILENCE_S = 0.25


@dataclass(frozen=True, kw_only=True)
class BenchSafety:
    """The bench's watchdogs (s, rad, N). Defaults put every fault at zero torque within 100 ms.

    Parameters
    ----------
    imu_max_age_s, motor_max_silence_s, motor_min_unanswered, max_transmit_failures
        As :class:`bowden.runtime.safety.SafetyConfig`: a stale IMU sample, replies missing to
        commands actually sent (either motor), consecutive failed sends.
    max_tension_n
        A load-cell reading above this stops the bench.
    range_margin_rad
        The elevation may overshoot the protocol's range by this much; beyond it the bench stops.
    max_temperature_c
        Either motor hotter than this stops the bench.
    imu_follow_spool_rad, imu_follow_min_rad
        Once the spool has moved ``imu_follow_spool_rad`` in a stroke, the elevation must have changed
        by ``imu_follow_min_rad`` (an IMU fallen off or not on the arm).
    load_hold_fraction, load_hold_window_s
        The mannequin motor must report at least this fraction of its load command (after its ramp);
        less for the window means it cannot hold the load.
    load_cell_check_pull_n, load_cell_min_n, load_cell_window_s
        While the TDU pulls more than ``load_cell_check_pull_n`` (its torque over the pulley radius),
        the load cell must read at least ``load_cell_min_n`` within the window.
    load_cell_min_fraction
        While the arm rests on the cable at a stroke's start, the load cell must read at least this
        fraction of the tension the load implies (load over the cuff's lever there) within the window:
        a dead load cell is found at any load, before the first stroke.
    load_cell_max_age_s
        The newest load-cell reading older than this stops the bench (counted, as the IMU's age, from
        the end of a host stall at most) if its reader kept trying; if the reader made no attempt
        either (a host that starves its thread), it is a gap in the data (:mod:`bowden.runtime.bench_cell`).
    load_cell_reader_max_idle_s
        A load cell's reader that has attempted no read for this long stops the bench.
    ramp_down_s
        Both torques ramp to zero over this long, then both motors leave motor mode.
    """

    imu_max_age_s: float = 0.04
    motor_max_silence_s: float = 0.03
    motor_min_unanswered: int = 5
    max_transmit_failures: int = 3
    max_tension_n: float = 250.0
    range_margin_rad: float = math.radians(10.0)
    max_temperature_c: float = 80.0
    imu_follow_spool_rad: float = 1.5
    imu_follow_min_rad: float = math.radians(2.0)
    load_hold_fraction: float = 0.5
    load_hold_window_s: float = 0.2
    load_cell_check_pull_n: float = 20.0
    load_cell_min_n: float = 2.0
    load_cell_window_s: float = 0.2
    load_cell_min_fraction: float = 0.3
    load_cell_max_age_s: float = 0.25
    load_cell_reader_max_idle_s: float = 1.0
    ramp_down_s: float = 0.03

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ParameterError(f"BenchSafety.{name} must be positive and finite, got {value!r}")
        if self.ramp_down_s > 0.1:
            raise ParameterError(f"BenchSafety.ramp_down_s must be at most 0.1 s, got {self.ramp_down_s}")
        if self.load_hold_fraction >= 1.0:
            raise ParameterError("BenchSafety.load_hold_fraction must be below 1")
        if self.load_cell_min_fraction >= 1.0:
            raise ParameterError("BenchSafety.load_cell_min_fraction must be below 1")

    def on_shared_host(self) -> BenchSafety:
        """These watchdogs for the simulated bench, whose devices are processes sharing this host's
        CPUs: a device peer the scheduler starves for a quarter second is the host, not a device
        (measured: "no reply to 32 commands in 31 ms" at load average 6.7 on 2 cores). The IMU's age
        and the motors' silence may reach 0.25 s; a device that stays silent is still found."""
        return replace(self, imu_max_age_s=max(self.imu_max_age_s, _SHARED_HOST_SILENCE_S),
                       motor_max_silence_s=max(self.motor_max_silence_s, _SHARED_HOST_SILENCE_S))


@dataclass(frozen=True, kw_only=True)
class BenchRunConfig:
    """How the bench runs the protocol.

    Parameters
    ----------
    protocol
        The identification protocol (speeds, loads, repetitions, range, hold, acceleration, gains,
        recording rate).
    rate_hz
        The loop's rate; rows are recorded at ``protocol.sample_rate_hz`` (a divisor of it). The
        motor holds each MIT position target until the next command and answers with the torque it
        applied just before it, so its reported torque is always sampled at the same point of the
        tracking error's sawtooth (kp·v/rate): at 400 Hz that biased both identified intercepts
        towards zero by 0.016–0.026 Nm on the simulated bench, at 1 kHz by ≤ 0.003 Nm (raising).
        Two motors at 1 kHz use about half of the 1 Mbit/s bus.
    spool_radius_m
        The TDU's pulley radius (the motor's pull without a load cell: torque / radius).
    slack
        The slack take-up before the first stroke (:class:`~bowden.runtime.slack.SlackTakeUp`).
    take_up_load_nm
        The mannequin's load while the slack is taken up (it holds the arm lightly as the cable
        tightens; a stroke's load ramps in later, with the arm held at the stroke's start).
    load_ramp_s
        A change of the mannequin's load is ramped over this long.
    position_speed_rad_s
        Largest spool speed of the unrecorded moves that bring the arm to a stroke's start (servoed
        on the IMU); strokes faster than this to an end not yet learned under their load are
        preceded by such a move to that end.
    geometry
        The cuff's geometry on the bench (the cable's lever about the shoulder): the spool's travel
        per degree, and the tension a load implies with the arm at rest (the load-cell check).
    wall_stiffness_nm_rad, wall_damping_nms_rad
        The soft walls the mannequin's motor puts beyond the range (half ``safety.range_margin_rad``
        past the protocol's high end; past its low end during a lowering stroke): a spring and a
        damper on top of the load, braking an arm flung past an end by a fast stroke before the
        range guard. 60 Nm/rad and
        1 Nm·s/rad stop the simulated mannequin arm (0.08 kg·m²) arriving at 2 rad/s within about
        4°, with 6 Nm at most (the AK80-9's peak is 18 Nm).
    stroke_timeout_factor
        A stroke that takes longer than this times its expected duration (plus 2 s) is a fault.
    safety
        :class:`BenchSafety`.
    latency, study
        The protocol's later segments, run after the identification strokes in this order (None: left
        out): the latency chirp (:class:`~bowden.protocol.bench.LatencyChirp`) and the study-like
        strokes (:class:`~bowden.protocol.bench.StudyStrokes`, the controller on the TDU). None by
        default here; ``bowden bench run`` runs both (its default protocol is all three segments).
    identification
        Run the identification strokes (False: only the later segments, e.g. ``bench validate``).
    fit
        The study-like fit (:class:`~bowden.protocol.bench.StudyFit`, ``bench validate --fit``): its
        blocks run after the latency chirp and before the study-like strokes, which then run the
        candidate the fit chose.
    mannequin_inertia_kgm2
        The mannequin arm's moment of inertia about the shoulder, fed forward by its motor along the
        study's reference (the simulated mannequin's: 0.08 kg·m²).
    model_digest
        ``bench validate``: the digest of the model the study-like blocks run
        (:func:`~bowden.model.model_record.controller_sha256`), so that a resume with another model is
        refused; None for ``bench run``, whose model is identified during the run.
    """

    protocol: BenchProtocol = field(default_factory=BenchProtocol)
    rate_hz: float = 1000.0
    spool_radius_m: float = 0.035
    slack: SlackTakeUp = field(default_factory=SlackTakeUp)
    take_up_load_nm: float = 0.3
    load_ramp_s: float = 0.3
    position_speed_rad_s: float = 1.0
    stroke_timeout_factor: float = 3.0
    wall_stiffness_nm_rad: float = 60.0
    wall_damping_nms_rad: float = 1.0
    geometry: CuffGeometry = field(default_factory=CuffGeometry)
    safety: BenchSafety = field(default_factory=BenchSafety)
    latency: LatencyChirp | None = None
    study: StudyStrokes | None = None
    identification: bool = True
    mannequin_inertia_kgm2: float = 0.08
    fit: StudyFit | None = None
    model_digest: str | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate_hz) and 50.0 <= self.rate_hz <= 2000.0):
            raise ParameterError(f"BenchRunConfig.rate_hz must be in [50, 2000], got {self.rate_hz}")
        ratio = self.rate_hz / self.protocol.sample_rate_hz
        if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-9:
            raise ParameterError(f"the recording rate ({self.protocol.sample_rate_hz:g} Hz) must divide the "
                                 f"loop rate ({self.rate_hz:g} Hz)")
        for name in ("spool_radius_m", "take_up_load_nm", "load_ramp_s", "position_speed_rad_s",
                     "stroke_timeout_factor", "wall_stiffness_nm_rad", "wall_damping_nms_rad",
                     "mannequin_inertia_kgm2"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ParameterError(f"BenchRunConfig.{name} must be positive, got {value!r}")

    def protocol_fingerprint(self) -> dict[str, object]:
        """The numbers a resumed recording must share with the one it continues."""
        p = self.protocol
        return {"spool_speeds_rad_s": list(p.spool_speeds_rad_s), "loads_nm": list(p.loads_nm),
                "repetitions": p.repetitions, "low_rad": p.low_rad, "high_rad": p.high_rad,
                "hold_s": p.hold_s, "sample_rate_hz": p.sample_rate_hz,
                "spool_acceleration_rad_s2": p.spool_acceleration_rad_s2,
                "position_gain_nm_rad": p.position_gain_nm_rad,
                "velocity_gain_nms_rad": p.velocity_gain_nms_rad, "identification": self.identification,
                "latency": None if self.latency is None else asdict(self.latency),
                "study": None if self.study is None else {**asdict(self.study),
                                                          "supports": list(self.study.supports),
                                                          "speeds": list(self.study.speeds),
                                                          "compensations": list(self.study.compensations)},
                **({} if self.fit is None else {"fit": _fit_fingerprint(self.fit)}),
                **({} if self.model_digest is None else {"model": self.model_digest})}

    @property
    def n_units(self) -> int:
        """The protocol's units in the order run (the journal's count): the identification strokes,
        the latency chirp, the study-like blocks."""
        strokes = self.protocol.n_strokes if self.identification else 0
        return strokes + (self.latency is not None) + len(self.study_blocks())

    def study_blocks(self) -> list[tuple[StudyBlock, StudyStrokes]]:
        """The study-like blocks in the order run, each with the strokes it runs: the fit's, then the
        study-like segment's (numbered on from the fit's, so ``block`` is unique in the recording)."""
        blocks: list[tuple[StudyBlock, StudyStrokes]] = []
        if self.fit is not None:
            strokes = self.fit.strokes(self.study)
            blocks += [(block, strokes) for block in self.fit.blocks()]
        if self.study is not None:
            offset = len(blocks)
            blocks += [(replace(block, index=block.index + offset), self.study)
                       for block in self.study.blocks()]
        return blocks


def _fit_fingerprint(fit: StudyFit) -> dict[str, object]:
    return {"grid": [list(point) for point in fit.grid], "candidates": list(fit.candidates),
            "support": fit.support, "speeds": list(fit.speeds), "repetitions": fit.repetitions}


@dataclass(frozen=True)
class BenchDevices:
    """The bench's devices: the TDU, the mannequin's motor, the IMU on its arm, the load cell, a clock."""

    tdu: BenchMotor
    mannequin: BenchMotor
    imu: ElevationSensor
    load_cell: TensionSensor
    clock: Clock


@dataclass
class BenchReport:
    """How a bench run ended."""

    strokes_done: int  # units of the protocol done: strokes, then the latency chirp, then study blocks
    strokes_total: int
    fault: str | None = None
    fault_at_s: float = math.nan  # clock time the fault was found
    safe_at_s: float = math.nan  # clock time both motors were out of motor mode (the end of the run)
    exit_errors: list[str] = field(default_factory=list)
    data_gaps: int = 0  # times the load cell's reader starved (host load); strokes with one ran again

    @property
    def complete(self) -> bool:
        return self.fault is None and self.strokes_done == self.strokes_total


class BenchFault(BowdenError):
    """A watchdog of the bench fired (the message names it); both motors are already safe."""


class BenchInterrupted(Exception):
    """The operator asked the run to stop (:meth:`BenchState.request_stop`, e.g. from a signal
    handler); raised at the start of the next cycle, where no device call is under way."""
