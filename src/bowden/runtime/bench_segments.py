"""The bench protocol's later segments in real time: the latency chirp and the study-like strokes.

After the identification strokes (docs/identification.md, "The protocol, exactly") the mannequin's
motor drives the arm itself, in MIT mode about a reference (its impedance mode): the IMU's elevation
against the joint's encoder along a chirp (segment 2: the IMU's latency), then the study's
minimum-jerk cycle while the TDU runs the controller — bowden's own control code, as ``bowden run``
runs it — with each compensation in turn (segment 3: which compensation tracks the load cell
better). Between blocks the arm is moved by the mannequin along a minimum-jerk path while the TDU
holds the chirp's low torque (the cable stays taut). Every watchdog of the strokes stays on; the
mannequin's motor must also follow its reference (within the range margin).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

import numpy as np

from bowden.control import Controller
from bowden.errors import TransmitError
from bowden.identify.study_recording import covers_its_cycles
from bowden.model import AssistanceParameters, desired_tension_n
from bowden.protocol.bench import MotorNoise, StudyBlock, StudyStrokes
from bowden.protocol.minimum_jerk import minimum_jerk_position
from bowden.runtime.bench_config import BenchFault
from bowden.runtime.bench_recording import STUDY_COLUMNS
from bowden.runtime.bench_state import PHASE_LATENCY, PHASE_MANNEQUIN_MOVE, PHASE_STUDY, joint_rad
from bowden.runtime.bench_strokes import _GAP_RETRIES, BenchStrokes
from bowden.runtime.realtime import at_normal_priority

_T = TypeVar("_T")
_CYCLE_PHASE = STUDY_COLUMNS.index("cycle_phase")
_log = logging.getLogger(__name__)
_SETTLE_S = 1.0  # the arm held still before a segment: the joint's offset to the IMU is measured then
_MOVE_SPEED_RAD_S = 0.5  # the mannequin's moves between blocks (peak speed of a minimum-jerk path)
# No move shorter than this: the block's rest (its reference held at the start, the mannequin's
# impedance on) brings the arm there, in the second a move would take.
_THERE_RAD = math.radians(5.0)
_FOLLOW_WINDOW_S = 0.2  # the joint this long off its reference by more than half the range margin
SPEED_CODES = {"V1": 1, "V2": 2, "V3": 3}  # the study recording's ``speed`` column
COMPENSATION_CODES = {"paper": 0, "dynamic": 1}  # its ``compensation`` column


def study_time_s(blocks: list[tuple[StudyBlock, StudyStrokes]]) -> float:
    """Roughly how long ``blocks`` take on a bench (s): each recorded block (``block_duration_s``),
    and before it the arm held still and moved to the cycle's start (from the previous block's end,
    already there: the move's shortest, 1 s, and 0.5 s still)."""
    return sum(strokes.block_duration_s(block.speed) + _SETTLE_S + 1.5 for block, strokes in blocks)


def support_code(support: float | str) -> float:
    """The study recording's ``support`` column: the fraction, 0 for the pretension condition."""
    return 0.0 if support == "pretension" else float(support)


class BenchSegments(BenchStrokes):
    """Runs the latency chirp and the study-like blocks, each recorded whole or not at all."""

    _off_reference_since = math.nan
    _segment_rows: list[tuple[float, ...]]

    # --- the mannequin in impedance mode -----------------------------------------------------------
    def _impedance_cycle(self, elevation_rad: float, velocity_rad_s: float, lift_nm: float, *,
                         kp: float, kd: float, tdu_torque_nm: float) -> float:
        """One cycle with the mannequin in MIT mode about ``elevation_rad`` and the TDU in torque mode;
        the clock time of the cycle."""
        now = self._begin_cycle()
        offset = self._joint.offset_rad
        # The motor's sense is the elevation's opposite (bench_state.joint_rad).
        target = -(elevation_rad + offset)
        self._mannequin_command_nm = 0.0  # no load to hold: the hold check is for torque mode
        try:
            state = self.devices.mannequin.command_mit(target, -velocity_rad_s, kp, kd, -lift_nm)
            self._mannequin_state = state or self._mannequin_state
            self._tdu_state = self.devices.tdu.command_torque(tdu_torque_nm) or self._tdu_state
            self._transmit_failures = 0
        except TransmitError as error:
            self._transmit_failed(error)
        self._check_motors(now)
        self._check_follows(now, elevation_rad)
        self._cycle += 1
        return now

    def _joint_elevation_rad(self) -> float:
        state = self._mannequin_state
        return self._joint.elevation_rad(joint_rad(state), self._elevation_rad) if state else math.nan

    def _check_follows(self, now: float, reference_rad: float) -> None:
        """The mannequin's joint within the range margin of its reference, or a fault in 0.2 s. (Its
        impedance is a wearer's, soft: the cable's error against the support law moves the arm, 5.5°
        at V3 on the simulated bench on a busy host.)"""
        error = self._joint_elevation_rad() - reference_rad
        if abs(error) <= self.config.safety.range_margin_rad:
            self._off_reference_since = math.nan
            return
        if math.isnan(self._off_reference_since):
            self._off_reference_since = now
        elif now - self._off_reference_since > _FOLLOW_WINDOW_S:
            raise BenchFault(f"the mannequin's motor does not follow its reference: the joint is at "
                             f"{math.degrees(reference_rad + error):.1f}° for "
                             f"{math.degrees(reference_rad):.1f}° (its gains, or its load too heavy)")

    def _hold_still(self, holding_nm: float, kp: float, kd: float) -> None:
        """Hold the arm where it is for ``_SETTLE_S`` and reference the joint's angle to the IMU's
        elevation over the second half (after a resume nothing was referenced yet)."""
        state = self._mannequin_state
        if state is None:
            raise BenchFault("the mannequin's motor has not reported its position")
        here = joint_rad(state)
        self._joint.offset_rad = here - self._elevation_rad
        offsets = []
        end = self._deadline + _SETTLE_S
        while self._deadline < end:
            self._impedance_cycle(here - self._joint.offset_rad, 0.0, 0.0, kp=kp, kd=kd,
                                  tdu_torque_nm=holding_nm)
            if self._cycle % self.record_every == 0:
                self._record_log(self._deadline)
            if self._deadline > end - _SETTLE_S / 2.0 and self._mannequin_state is not None:
                offsets.append(joint_rad(self._mannequin_state) - self._elevation_rad)
        self._joint.offset_rad = float(np.mean(offsets)) if offsets else self._joint.offset_rad

    def _hold_while(self, task: Callable[[], _T]) -> _T:
        """Run ``task`` on a thread while the loop holds the arm still (the mannequin in MIT mode, the
        TDU at the chirp's holding torque); its result, or its exception. The motors are commanded
        every cycle meanwhile: a loop that paused for the seconds an identification takes would leave
        them on their last command (when the simulated mannequin held its last MIT torque, a weightless
        arm drifted to 141°). The task runs at normal priority, not the loop's."""
        holding = self.config.latency.holding_torque_nm if self.config.latency else 0.5
        study = self.config.study
        kp, kd = (study.stiffness_nm_rad, study.damping_nms_rad) if study else (25.0, 2.5)
        self._phase = PHASE_MANNEQUIN_MOVE
        self._hold_still(holding, kp, kd)
        here = self._joint_elevation_rad()
        executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="bench-task")
        try:
            future = executor.submit(_at_normal_priority, task)
            while not future.done():
                self._impedance_cycle(here, 0.0, 0.0, kp=kp, kd=kd, tdu_torque_nm=holding)
                if self._cycle % self.record_every == 0:
                    self._record_log(self._deadline)
            return future.result()
        finally:
            executor.shutdown(wait=False)  # a fault meanwhile: the motors are made safe at once

    def _move_arm(self, to_rad: float, holding_nm: float, kp: float, kd: float) -> None:
        """Move the arm with the mannequin's motor along a minimum-jerk path to ``to_rad`` (logged, not
        recorded), the TDU holding ``holding_nm``."""
        self._phase = PHASE_MANNEQUIN_MOVE
        self._hold_still(holding_nm, kp, kd)
        start = self._joint_elevation_rad()
        if abs(to_rad - start) < _THERE_RAD:  # a block after a block: its arm ended 2-4° above the low end
            return
        duration = max(1.0, 1.875 * abs(to_rad - start) / _MOVE_SPEED_RAD_S)
        began = self._deadline
        while self._deadline - began < duration + 0.5:
            tau = min((self._deadline - began) / duration, 1.0)
            position = float(minimum_jerk_position(tau))
            elevation = start + (to_rad - start) * position
            velocity = (to_rad - start) * 30.0 * tau**2 * (1.0 - tau) ** 2 / duration
            self._impedance_cycle(elevation, velocity, 0.0, kp=kp, kd=kd, tdu_torque_nm=holding_nm)
            if self._cycle % self.record_every == 0:
                self._record_log(self._deadline)

    # --- segment 2: the latency chirp -------------------------------------------------------------
    def _run_latency(self) -> np.ndarray:
        """The chirp (:class:`~bowden.protocol.bench.LatencyChirp`); its rows (``LATENCY_COLUMNS``)."""
        chirp = self.config.latency
        assert chirp is not None
        study = self.config.study
        kp, kd = (study.stiffness_nm_rad, study.damping_nms_rad) if study else (25.0, 2.5)
        # Position mode: stiff, so the arm follows the chirp whatever the cable does.
        kp, kd = max(kp, 100.0), max(kd, 2.5)
        self._segment_high_rad = chirp.centre_rad + chirp.amplitude_rad
        self._move_arm(chirp.centre_rad, chirp.holding_torque_nm, kp, kd)
        self._phase = PHASE_LATENCY
        rows: list[tuple[float, ...]] = []
        began = self._deadline
        while self._deadline - began < chirp.duration_s:
            elevation, velocity = chirp.elevation(self._deadline - began)
            self._impedance_cycle(elevation, velocity, 0.0, kp=kp, kd=kd,
                                  tdu_torque_nm=chirp.holding_torque_nm)
            if self._cycle % self.record_every == 0:
                rows.append((self._time_s(self._deadline), self._elevation_rad, self._joint_elevation_rad()))
                self._record_log(self._deadline)
        return np.array(rows)

    # --- segment 3: the study-like strokes --------------------------------------------------------
    def _run_study_whole(self, block: StudyBlock, controller: Controller, study: StudyStrokes) -> np.ndarray:
        """The block, run again while the load cell's reader starved during its cycles (its rows would
        hold a stale tension, and a fit would judge a candidate on it) or when its rows stop short of
        its last cycle's end (a host stall there: the judge would leave that repetition out), up to
        ``_GAP_RETRIES`` times as a stroke; the same mannequin noise each time (:class:`MotorNoise`
        starts over)."""
        for _ in range(_GAP_RETRIES + 1):
            rows = self._run_study_block(block, controller, study)
            whole = covers_its_cycles(rows[:, _CYCLE_PHASE] if rows.size else rows, study.repetitions)
            if not self._gap_in_attempt and whole:
                return rows
            why = "a gap in the load cell's data" if self._gap_in_attempt else "its last cycle cut short"
            _log.warning("bench: study-like block %d is run again (%s)", block.index + 1, why)
        raise BenchFault(f"study-like block {block.index + 1}: the load cell's reader was starved or the "
                         f"loop stalled in {_GAP_RETRIES + 1} attempts in a row: the host is too busy")

    def _run_study_block(self, block: StudyBlock, controller: Controller, study: StudyStrokes) -> np.ndarray:
        """One block of ``study``'s strokes: rest at the low end, then the cycles with the controller on
        the TDU; its rows (``STUDY_COLUMNS``)."""
        cycle = study.cycle(block.speed)
        kp, kd = study.stiffness_nm_rad, study.damping_nms_rad
        holding = self.config.latency.holding_torque_nm if self.config.latency else 0.5
        self._segment_high_rad = cycle.high_rad
        self._move_arm(cycle.low_rad, holding, kp, kd)
        self._phase = PHASE_STUDY
        self._gap_in_attempt = False  # a gap while the arm was moved there is not in the block's rows
        assistance = AssistanceParameters(support=block.support,  # type: ignore[arg-type]
                                          floor_tension_n=10.0, pretension_n=10.0)
        geometry, arm = controller.geometry, controller.arm
        every = max(1, round(self.config.rate_hz / study.controller_rate_hz))
        codes = (block.index, support_code(block.support), SPEED_CODES[block.speed],
                 COMPENSATION_CODES[block.compensation])
        fit_codes = (float(block.fit), block.candidate if block.fit else -1)
        controller.reset()
        noise = MotorNoise(study, block, self.period_s)
        torque = 0.0
        command: Any = None
        rows: list[tuple[float, ...]] = []
        began = self._deadline
        duration = study.block_duration_s(block.speed)
        while self._deadline - began < duration:
            t = self._deadline - began - study.rest_s
            elevation, velocity, acceleration = _reference(cycle, t, study.repetitions)
            law = desired_tension_n(elevation, arm, geometry, assistance)
            # The mannequin knows the suit: the support law's nominal torque and its arm's inertia are
            # fed forward, the impedance takes up the rest (sim/bench_study's mannequin).
            lift = self.config.mannequin_inertia_kgm2 * acceleration - law * geometry.moment_arm_m(elevation)
            lift += noise.torque_nm(lift)  # a wearer's arm is never that smooth (MotorNoise)
            if self._cycle % every == 0:
                sample = self.devices.imu.read()
                tdu = self._tdu_state
                command = controller.step(self._deadline, self._elevation_rad,
                                          sample.elevation_velocity_rad_s if sample else 0.0,
                                          tdu.velocity_rad_s if tdu else math.nan,
                                          tdu.torque_nm if tdu else math.nan)
                if command.faults:
                    raise BenchFault(f"the controller reports fault bits {command.faults} "
                                     f"({block.compensation}, {block.speed})")
                torque = command.torque_nm
            self._impedance_cycle(elevation, velocity, lift, kp=kp, kd=kd, tdu_torque_nm=torque)
            if self._cycle % self.record_every == 0 and t < study.repetitions * cycle.period_s:
                rows.append((*self._study_row(codes, t / cycle.period_s, elevation, arm, geometry, assistance,
                                              command.tension_n if command is not None else math.nan),
                             *fit_codes))
                self._record_log(self._deadline)
        return np.array(rows)

    def _study_row(self, codes: tuple[float, ...], cycle_phase: float, reference_rad: float, arm: Any,
                   geometry: Any, assistance: AssistanceParameters, command_tension_n: float,
                   ) -> tuple[float, ...]:
        tdu = self._tdu_state
        joint = self._joint_elevation_rad()
        law = desired_tension_n(joint, arm, geometry, assistance)  # at the arm's true elevation
        return (self._time_s(self._deadline), *codes, cycle_phase,
                tdu.torque_nm if tdu else math.nan, tdu.velocity_rad_s if tdu else math.nan,
                self._tension_n, self._elevation_rad, joint, reference_rad, law, command_tension_n)


def _reference(cycle: Any, t: float, repetitions: int) -> tuple[float, float, float]:
    """The study's reference at ``t`` from the first cycle's start: elevation, velocity and
    acceleration (central difference of the velocity over 1 ms); at rest at the low end outside the
    cycles."""
    if t < 0.0 or t >= repetitions * cycle.period_s:
        return cycle.low_rad, 0.0, 0.0
    elevation = float(cycle.elevation_rad(t))
    velocity = float(cycle.elevation_velocity_rad_s(t))
    h = 5e-4
    change = cycle.elevation_velocity_rad_s(t + h) - cycle.elevation_velocity_rad_s(t - h)
    acceleration = float(change) / (2.0 * h)
    return elevation, velocity, acceleration


def _at_normal_priority(task: Callable[[], _T]) -> _T:
    """``task`` on the calling thread at normal priority: the loop's real-time priority, which the
    thread inherited, is for the loop (:func:`~bowden.runtime.realtime.at_normal_priority`)."""
    with at_normal_priority():
        return task()
