"""The state a bench run carries from cycle to cycle, and the small helpers that read it.

:class:`BenchState` is the base of :class:`bowden.runtime.bench.BenchRun` (one job per module: the
state here, :mod:`~bowden.runtime.bench_sensing` the sensors and their checks,
:mod:`~bowden.runtime.bench_cycle` one loop cycle, :mod:`~bowden.runtime.bench_positioning` the moves
between strokes, :mod:`~bowden.runtime.bench_strokes` the strokes, :mod:`~bowden.runtime.bench_safe_stop`
the safe stop, :mod:`~bowden.runtime.bench` the run). The phase constants are the device log's ``phase``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from bowden.hardware.protocols import MotorState
from bowden.protocol.bench import BenchStroke
from bowden.runtime.bench_cell import LoadCellWatch
from bowden.runtime.bench_config import BenchDevices, BenchInterrupted, BenchRunConfig
from bowden.runtime.bench_ends import LearnedEnds
from bowden.runtime.bench_recording import BenchRecordingWriter
from bowden.runtime.bench_walls import JointReference, SoftWalls

PHASE_HOLD, PHASE_STROKE, PHASE_POSITION, PHASE_TAKE_UP, PHASE_SETTLE = 0, 1, 2, 3, 4
# The later segments: the latency chirp, the study-like strokes, the mannequin's moves between them.
PHASE_LATENCY, PHASE_STUDY, PHASE_MANNEQUIN_MOVE = 5, 6, 7
# The arm is at rest when its elevation's speed stays below _REST_SPEED_RAD_S for _REST_WINDOW_S: the
# speed is the difference of two running means of the IMU's elevation (time constants _REST_FAST_S
# and _REST_SLOW_S) over the difference of their lags. (Not the gyroscope: with the arm hanging
# near 0° the elevation's rate is ill-conditioned.)
_REST_SPEED_RAD_S = math.radians(5.0)
_REST_FAST_S = 0.03
_REST_SLOW_S = 0.15
_REST_WINDOW_S = 0.1


Progress = Callable[[BenchStroke, int], None]


def joint_rad(state: MotorState) -> float:
    """The mannequin joint's angle in the elevation's sense (> 0 raising) from its motor's state. The
    motor loads the arm down with a positive torque (``--mannequin-direction``), and an AK motor's
    position shares its torque's sign: the elevation is minus the position (plus an offset,
    :class:`~bowden.runtime.bench_walls.JointReference`)."""
    return -state.position_rad


class BenchState:
    """The devices, the configuration, the recording and every value the run carries between cycles."""

    def __init__(self, devices: BenchDevices, config: BenchRunConfig, writer: BenchRecordingWriter, *,
                 progress: Progress | None = None) -> None:
        self.devices = devices
        self.config = config
        self.writer = writer
        self.progress = progress
        self.period_s = 1.0 / config.rate_hz
        self.record_every = round(config.rate_hz / config.protocol.sample_rate_hz)
        self.strokes = config.protocol.strokes()
        self._deadline = math.nan
        self._cycle = 0
        self._time_offset_s = 0.0
        self._origin_s = math.nan
        self._rows: list[tuple[float, ...]] = []
        self._log_rows: list[tuple[float, ...]] = []
        self._target_rad = math.nan  # the TDU's position target (multi-turn spool, rad)
        self._velocity_rad_s = 0.0  # the TDU's velocity target
        self._load_command_nm = 0.0  # the load (ramped), without the wall's
        self._mannequin_command_nm = 0.0  # what the mannequin's motor is told: the load and the wall
        margin = config.safety.range_margin_rad / 2.0
        self._walls = SoftWalls(config.protocol.low_rad - margin, config.protocol.high_rad + margin,
                                config.wall_stiffness_nm_rad, config.wall_damping_nms_rad)
        self._joint = JointReference()  # the mannequin's joint angle against the IMU's elevation
        self._load_from_nm = 0.0
        self._load_to_nm = 0.0
        self._load_ramp_start_s = -math.inf
        self._transmit_failures = 0
        self._tdu_state: MotorState | None = None
        self._mannequin_state: MotorState | None = None
        self._low_load_since = math.nan
        self._deaf_cell_since = math.nan
        self._tension_n = math.nan
        self._elevation_rad = math.nan
        self._stroke: BenchStroke | None = None
        self._segment_high_rad = -math.inf  # the highest elevation of the later segment under way
        self._phase = PHASE_HOLD
        self._ends = LearnedEnds(config.geometry, config.spool_radius_m, writer.resume_point.learned)
        self._stall_end_s = -math.inf  # when the last host stall ended (clock time)
        self._last_cycle_s = math.nan  # clock time of the last cycle (the target advances by the clock)
        self._cycle_dt_s = self.period_s
        self._arrival = 0.0  # the direction the spool last moved in (±1): the friction's branch
        self._rest_speed_rad_s = math.inf  # the elevation's speed, from two running means
        self._fast_mean_rad = self._slow_mean_rad = math.nan
        self._rest_since = math.nan
        self.scouting_moves = 0  # slow moves to learn an end before a fast stroke
        self._furthest_rad = math.nan  # the furthest elevation of the stroke under way
        self._cell_watch = LoadCellWatch(config.safety.load_cell_max_age_s,
                                         config.safety.load_cell_reader_max_idle_s)
        self._gap_in_attempt = False  # the load cell's reader starved while this attempt was recorded
        self._stop_reason: str | None = None  # set by request_stop (a signal handler), seen each cycle

    def request_stop(self, reason: str) -> None:
        """Ask the run to stop safely at the start of its next cycle (safe in a signal handler: one
        attribute write). A request during the safe stop changes nothing: the stop goes on."""
        self._stop_reason = reason

    def _stop_if_requested(self) -> None:
        if self._stop_reason is not None:
            raise BenchInterrupted(self._stop_reason)

    @property
    def phase(self) -> int:
        """What the bench does now (``PHASE_*``; the device log's ``phase``)."""
        return self._phase

    @property
    def stroke_under_way(self) -> BenchStroke | None:
        """The stroke being run (its positioning and hold included), None between runs."""
        return self._stroke

    def _set_load(self, load_nm: float) -> None:
        if load_nm == self._load_to_nm:
            return
        self._load_from_nm = self._load_command_nm
        self._load_to_nm = load_nm
        self._load_ramp_start_s = self.devices.clock.now()

    def _load_now(self, now: float) -> float:
        fraction = min(max((now - self._load_ramp_start_s) / self.config.load_ramp_s, 0.0), 1.0)
        return self._load_from_nm + fraction * (self._load_to_nm - self._load_from_nm)

    def _wall_torque_nm(self) -> float:
        """The soft walls' torque now (:mod:`bowden.runtime.bench_walls`), on the joint's encoder."""
        state = self._mannequin_state
        if state is None:
            return 0.0
        elevation = self._joint.elevation_rad(joint_rad(state), self._elevation_rad)
        lowering = self._stroke is not None and not self._stroke.raising and self._phase in (
            PHASE_STROKE, PHASE_SETTLE)
        return self._walls.torque_nm(elevation, -state.velocity_rad_s, lowering=lowering)

    def _reference_joint(self) -> None:
        state = self._mannequin_state
        # Both still (an IMU that froze reads as still while the joint moves).
        if state is not None and self._rest_speed_rad_s <= _REST_SPEED_RAD_S \
                and abs(state.velocity_rad_s) <= _REST_SPEED_RAD_S:
            self._joint.update(joint_rad(state), self._elevation_rad, self._cycle_dt_s)

    def _spool_position(self) -> float:
        return self._tdu_state.position_rad if self._tdu_state is not None else 0.0

    def _pull_n(self) -> float:
        """The TDU's pull on the cable estimated from its torque (N), for checks without the load cell."""
        torque = self._tdu_state.torque_nm if self._tdu_state is not None else 0.0
        return torque / self.config.spool_radius_m

    def _at_rest(self) -> bool:
        """The arm has been still (the IMU's elevation speed) for ``_REST_WINDOW_S``."""
        now = self.devices.clock.now()
        if self._rest_speed_rad_s > _REST_SPEED_RAD_S:
            self._rest_since = math.nan
            return False
        if math.isnan(self._rest_since):
            self._rest_since = now
        return now - self._rest_since >= _REST_WINDOW_S

    def _spool_per_elevation(self, elevation_rad: float) -> float:
        """Spool radians per radian of elevation: the cable's lever over the pulley's (cuff geometry),
        at least a tenth of the lever at 90° (near the bottom the lever vanishes)."""
        geometry = self.config.geometry
        lever = max(geometry.moment_arm_m(elevation_rad), 0.1 * geometry.moment_arm_m(math.pi / 2.0))
        return lever / self.config.spool_radius_m

    def _spool_travel(self, from_rad: float, to_rad: float) -> float:
        """The spool's travel (rad, > 0 reeling in) that moves the arm between two elevations by the
        cuff's geometry (the cable's stretch aside)."""
        length = self.config.geometry.cable_length_m
        return (length(from_rad) - length(to_rad)) / self.config.spool_radius_m
