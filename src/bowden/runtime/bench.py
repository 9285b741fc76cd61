"""The identification protocol on a mannequin bench, in a fixed-rate loop over the devices' wires.

Paper, "Data acquisition": the tendon driver unit (TDU, the suit's AK60-6) moves the spool at a
quasi-constant velocity across the arm's range while the mannequin's own motor loads the arm with a
constant torque; the load cell, the IMU on the mannequin's arm and both motors are recorded. Here:

* the TDU tracks a trajectory in MIT mode (``kp``, ``kd`` of the protocol; the target advances at
  the commanded velocity by the clock, with trapezoidal ramps at the protocol's acceleration), the
  mannequin motor is commanded in torque (its load ramps when it changes);
* a stroke brakes where the spool stood when the arm last came to rest at its end under the same
  load, arriving the same way (:mod:`bowden.runtime.bench_ends`, journalled for a resume); a slow
  stroke to an end not visited yet brakes on the elevation-per-spool ratio measured so far, aiming
  short; a faster one is preceded by a slow, unrecorded move to that end and back to learn it. A
  stroke is recorded until the arm rests; one that rests short of its end is run again (three
  attempts, then a fault that says so) (docs/identification.md, "On your bench");
* the mannequin's motor brakes an arm flung beyond the range with soft walls on its load
  (:mod:`bowden.runtime.bench_walls`);
* every run starts by taking up the cable's slack (:mod:`bowden.runtime.slack`); before each stroke
  the TDU servoes the arm to the stroke's start on the IMU and holds it there while the mannequin's
  load ramps to the stroke's, until the arm rests there (logged, not recorded);
* every cycle is watched, and any fault brings both motors to zero torque and out of motor mode
  within ``ramp_down_s`` plus a cycle: stale IMU, elevation out of the range with its margin, tension
  over the limit, a silent or failing motor, transmit failures, an IMU that does not follow the
  spool, a mannequin that does not hold its load, a load cell that reads nothing while the TDU pulls
  or while the arm rests on the cable under its load, an arm that cannot be held at a stroke's start
  under its load, a stroke that does not end in time or does not reach its end. A load cell whose
  reader the host starves is a gap in the data, not a fault (:mod:`bowden.runtime.bench_cell`):
  the stroke recorded with it is run again.

Strokes are written by :class:`~bowden.runtime.bench_recording.BenchRecordingWriter` as they complete,
so a stop loses at most the stroke under way, and a resumed run skips what is on disk.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from bowden.control import Controller, build_controller
from bowden.errors import BowdenError, HardwareError, OutputFileError
from bowden.model import CompensationModel, Subject
from bowden.protocol.bench import StudyBlock, StudyStrokes
from bowden.runtime.bench_config import (
    BenchDevices,
    BenchFault,
    BenchInterrupted,
    BenchMotor,
    BenchReport,
    BenchRunConfig,
    BenchSafety,
    FitModels,
)
from bowden.runtime.bench_recording import LOG_COLUMNS, RECORDING_COLUMNS, BenchRecordingWriter
from bowden.runtime.bench_safe_stop import safe_stop
from bowden.runtime.bench_segments import BenchSegments
from bowden.runtime.bench_state import (
    PHASE_HOLD,
    PHASE_POSITION,
    PHASE_SETTLE,
    PHASE_STROKE,
    PHASE_TAKE_UP,
    Progress,
)
from bowden.runtime.slack import take_up_slack

_log = logging.getLogger(__name__)

_FIRST_SAMPLE_WAIT_S = 0.5
_TAKE_UP_LIFT_RAD = math.radians(3.0)


class BenchRun(BenchSegments):
    """Runs the protocol's units (the identification strokes, the latency chirp, the study-like
    blocks) from ``writer.resume_point`` on, recording each as it completes.

    ``model_source(recording, latency_recording)`` gives the model the study-like blocks run the
    controller on, called once before the first of them (the CLI identifies it from what the run
    recorded); ``announce`` is told each later segment's block as it starts; ``fit_models`` gives a
    study-like fit's blocks their candidates and the study-like blocks after it the one chosen."""

    def __init__(self, devices: BenchDevices, config: BenchRunConfig, writer: BenchRecordingWriter, *,
                 progress: Progress | None = None,
                 model_source: Callable[[Path, Path | None], CompensationModel] | None = None,
                 announce: Callable[[str], None] | None = None,
                 fit_models: FitModels | None = None) -> None:
        super().__init__(devices, config, writer, progress=progress)
        if not config.identification:
            self.strokes = []
        self.model_source = model_source
        self.announce = announce
        self.fit_models = fit_models
        self._model: CompensationModel | None = None
        self._chosen: CompensationModel | None = None

    def run(self) -> BenchReport:
        """Enable both motors, take up the slack, run the remaining strokes, leave both safe.

        A fault brings both motors to the safe state and is reported (never raised); a device that
        does not answer when enabled raises :class:`~bowden.errors.HardwareError` with nothing enabled.
        """
        done = self.writer.resume_point.strokes_done
        report = BenchReport(strokes_done=done, strokes_total=self.config.n_units)
        # Times continue a second after everything written before (the device log included).
        last = self.writer.resume_point.last_time_s
        self._time_offset_s = last + (1.0 if last > 0.0 else 0.0)
        self._enable()
        try:
            self._start_clock()
            self._take_up_slack()
            for index in range(done, self.config.n_units):
                self._log_rows = []
                self._run_unit(index)
                report.strokes_done = index + 1
            self._stroke = None
            if self.config.n_units == len(self.strokes):  # no later segment: the load off, held still
                self._finish_load()
        except BenchFault as fault:
            report.fault = str(fault)
            report.fault_at_s = self.devices.clock.now()
            report.safe_at_s = self._safe_stop(report.exit_errors)
            report.data_gaps = self._cell_watch.gaps
            self._keep_partial_log()
            return report
        except BaseException as error:  # a stop asked for, a bug, Ctrl-C, a full disk: the motors first
            report.safe_at_s = self._safe_stop(report.exit_errors)
            report.data_gaps = self._cell_watch.gaps
            self._keep_partial_log()
            if isinstance(error, BenchInterrupted | KeyboardInterrupt):
                report.fault = "interrupted"
                return report
            raise
        report.safe_at_s = self._safe_stop(report.exit_errors)
        report.data_gaps = self._cell_watch.gaps
        return report

    def _run_unit(self, index: int) -> None:
        """Run and record unit ``index`` of the protocol: an identification stroke, the latency chirp
        or a study-like block (``BenchRunConfig.n_units``)."""
        strokes = len(self.strokes)
        if index < strokes:
            stroke = self._stroke = self.strokes[index]
            self._run_covering(stroke)
            self._write(lambda: self.writer.write_stroke(np.array(self._rows), np.array(self._log_rows),
                                                         index + 1, learned=self._ends.to_json()))
            if self.progress is not None:
                self.progress(stroke, strokes)
            return
        self._stroke = None
        self._target_rad = self._spool_position()  # the TDU runs in torque mode from here on
        self._velocity_rad_s = 0.0
        latency = self.config.latency
        if index == strokes and latency is not None:
            self._say(f"latency chirp: {latency.duration_s:g} s, the mannequin moves the arm")
            rows = self._run_latency()
            self._write(lambda: self.writer.write_segment("latency", rows, np.array(self._log_rows),
                                                          index + 1))
            return
        blocks = self.config.study_blocks()
        block, study = blocks[index - strokes - (latency is not None)]
        self._say(self._describe(block, len(blocks)))
        rows = self._run_study_whole(block, self._controller_for(block, study), study)
        self._write(lambda: self.writer.write_segment("study", rows, np.array(self._log_rows), index + 1))

    def _write(self, action: Callable[[], None]) -> None:
        try:
            action()
        except OutputFileError as error:  # a full disk: stop safely, what was written before stays
            raise BenchFault(f"recording failed: {error}") from None

    def _say(self, text: str) -> None:
        if self.announce is not None:
            self.announce(text)

    def _describe(self, block: StudyBlock, blocks: int) -> str:
        what = f"{block.compensation} compensation"
        if block.fit and block.candidate >= 0 and self.config.fit is not None:
            what = f"candidate {block.candidate} ({self.config.fit.describe(block.candidate)})"
        kind = "study-like fit block" if block.fit else "study-like block"
        return f"{kind} {block.index + 1} of {blocks}: support {block.support}, {block.speed}, {what}"

    def _controller_for(self, block: StudyBlock, study: StudyStrokes) -> Controller:
        """The controller ``bowden run`` would build for the block's support and compensation, on the
        model the bench identified (or was given) — a fit's candidate of it in a fit's block, and the
        candidate the fit chose in the study-like blocks after a fit."""
        model = self._block_model(block)
        if block.compensation == "dynamic" and model.dynamic is None:
            raise BenchFault("the model has no dynamic compensation for the study-like segment")
        subject = Subject(height_m=study.subject_height_m, mass_kg=study.subject_mass_kg,
                          sex=study.subject_sex)  # type: ignore[arg-type]
        return build_controller(model=model, support=block.support,  # type: ignore[arg-type]
                                subject=subject, hand_load_kg=study.hand_load_kg,
                                geometry=self.config.geometry,
                                compensation=block.compensation)  # type: ignore[arg-type]

    def _block_model(self, block: StudyBlock) -> CompensationModel:
        model = self._base_model()
        if self.config.fit is None or (block.fit and block.candidate < 0):
            return model
        if self.fit_models is None:
            raise BenchFault("the study-like fit needs its candidates' models (none were given)")
        fit_models = self.fit_models
        try:
            if block.fit:
                return fit_models.candidate(model, block.candidate)
            if self._chosen is None:  # once, from the fit's blocks on disk (a resume reads them again)
                study_path = self.writer.segment_path("study")
                self._chosen = self._hold_while(lambda: fit_models.chosen(model, study_path))
            return self._chosen
        except BowdenError as error:
            raise BenchFault(f"the study-like fit: {error}") from None

    def _base_model(self) -> CompensationModel:
        if self._model is None:
            if self.model_source is None:
                raise BenchFault("the study-like segment needs a model (none was given)")
            latency = self.writer.segment_path("latency") if self.config.latency is not None else None
            try:
                source = self.model_source
                self._model = self._hold_while(lambda: source(self.writer.data_path, latency))
            except BowdenError as error:  # a recording identify refuses: said, the motors safe
                raise BenchFault(f"no model for the study-like segment from what was recorded: "
                                 f"{error}") from None
        return self._model

    def _keep_partial_log(self) -> None:
        """The device log of the stroke under way when the run stopped (the stroke is not recorded)."""
        rows, self._log_rows = self._log_rows, []
        if rows:
            try:
                self.writer.write_log(np.array(rows))
            except BowdenError as error:
                _log.error("bench: %s", error)

    def _enable(self) -> None:
        tdu, mannequin = self.devices.tdu, self.devices.mannequin
        try:
            self._mannequin_state = mannequin.enable()
        except HardwareError as error:
            raise HardwareError(f"the mannequin's motor does not answer: {error}") from None
        try:
            self._mannequin_state = mannequin.command_torque(0.0) or self._mannequin_state
            self._tdu_state = tdu.enable()
        except HardwareError as error:
            _quietly(mannequin.disable)
            raise HardwareError(f"the TDU's motor does not answer: {error}") from None
        self._target_rad = self._tdu_state.position_rad

    def _start_clock(self) -> None:
        clock = self.devices.clock
        now = clock.now()
        waited_until = now + _FIRST_SAMPLE_WAIT_S
        while self.devices.imu.read() is None:  # the first sample after the calibration
            if clock.now() > waited_until:
                raise BenchFault(f"no IMU sample within {_FIRST_SAMPLE_WAIT_S:g} s of enabling the motors")
            clock.sleep_until(clock.now() + 0.001)
            self._stop_if_requested()
        now = clock.now()
        self._origin_s = now
        self._deadline = now
        self._last_cycle_s = now
        self._stall_end_s = now  # sample ages count from here at most: nothing was read before

    def _take_up_slack(self) -> None:
        self._phase = PHASE_TAKE_UP
        slack = self.config.slack

        start_elevation = math.nan
        stalled_since = math.nan

        def cycle(velocity_rad_s: float, kd: float) -> float:
            nonlocal start_elevation, stalled_since
            self._cycle_once(velocity_rad_s=velocity_rad_s, kp=0.0, kd=kd)
            if math.isnan(start_elevation):
                start_elevation = self._elevation_rad
            if self._elevation_rad - start_elevation > _TAKE_UP_LIFT_RAD:
                # The cable is taut and lifts the arm: near the top of the range a light load balances
                # less than the pretension.
                return math.inf
            stalled_since = self._check_take_up_cell(velocity_rad_s, stalled_since)
            return self._tension_n

        # The mannequin holds the arm lightly against the cable as it tightens: a heavy load would pull
        # it to the bottom of its travel, where the cable's lever is too short to lift it again; the
        # stroke's load ramps in later, with the arm held at the stroke's start.
        self._set_load(self.config.take_up_load_nm)
        take_up_slack(slack, cycle, period_s=self.period_s, fail=BenchFault)
        self._arrival = 1.0
        state = self._tdu_state
        self._target_rad = state.position_rad if state is not None else self._target_rad
        self._velocity_rad_s = 0.0

    def _finish_load(self) -> None:
        self._set_load(0.0)
        self._dwell(self.config.load_ramp_s, PHASE_HOLD)

    def _safe_stop(self, errors: list[str]) -> float:
        """Both motors to the safe state (:func:`~bowden.runtime.bench_safe_stop.safe_stop`)."""
        tdu_torque = self._tdu_state.torque_nm if self._tdu_state is not None else 0.0
        return safe_stop(self.devices, period_s=self.period_s, ramp_down_s=self.config.safety.ramp_down_s,
                         tdu_torque_nm=tdu_torque, mannequin_torque_nm=self._mannequin_command_nm,
                         errors=errors)


def _quietly(action: Callable[[], None]) -> None:
    try:
        action()
    except (HardwareError, OSError) as error:
        _log.warning("bench: %s", error)


__all__ = [
    "LOG_COLUMNS", "PHASE_HOLD", "PHASE_POSITION", "PHASE_SETTLE", "PHASE_STROKE", "PHASE_TAKE_UP",
    "RECORDING_COLUMNS", "BenchDevices", "BenchFault", "BenchInterrupted", "BenchMotor", "BenchReport",
    "BenchRun", "BenchRunConfig", "BenchSafety", "Progress",
]
