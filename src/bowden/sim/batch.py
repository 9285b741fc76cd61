"""Batch simulation of the paper's protocol for a virtual cohort.

Each participant performs every condition (no suit first, the others in a seeded random order) at
every speed, ten raise-and-lower repetitions of the minimum-jerk reference each, with the paper's
controller at 500 Hz on the IMU's elevation and the plant integrated at 4 kHz. A trial is one compiled
loop (:func:`bowden.sim._batch_kernel.run_trial`); trials run one after the other.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from bowden import contracts as c
from bowden.control import Controller, ControllerLimits, build_controller
from bowden.errors import ParameterError
from bowden.model import CompensationModel
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.sim import _batch_kernel as bk
from bowden.sim import _kernels as k
from bowden.sim.parameters import SuitParameters, check_seed
from bowden.sim.participants import ExpectedAssistance, VirtualParticipant, human_vector
from bowden.sim.plant import equilibrium_state, pack_parameters
from bowden.sim.questionnaires import questionnaire_answers
from bowden.sim.results import (
    COCONTRACTION,
    CORRECTION_TORQUE,
    LIMIT_FLAGS,
    SHEATH_STUCK,
    SHOULDER_TORQUE,
    TRUE_ELEVATION,
    TRUE_ELEVATION_VELOCITY,
    TRUE_TENSION,
    TRUTH_SIGNALS,
    CohortSimulation,
    TrialSimulation,
)
from bowden.sim.sensor_readings import MOTOR_REPLY_LIMITS, ak60_torque, ak60_velocity, load_cell_reading

_OUTPUT_NAMES = {
    bk.O_REFERENCE: c.TRIAL_REFERENCE_ELEVATION,
    bk.O_ELEVATION: c.TRIAL_ELEVATION,
    bk.O_VELOCITY: c.TRIAL_ELEVATION_VELOCITY,
    bk.O_DESIRED_TENSION: c.TRIAL_DESIRED_TENSION,
    bk.O_MOMENT_ARM: c.TRIAL_MOMENT_ARM,
    bk.O_COMMANDED_TORQUE: c.TRIAL_COMMANDED_TORQUE,
    bk.O_MOTOR_TORQUE: c.TRIAL_MOTOR_TORQUE,
    bk.O_MOTOR_VELOCITY: c.TRIAL_MOTOR_VELOCITY,
    bk.O_TENSION: c.TRIAL_TENSION,
    bk.O_FAULT: c.TRIAL_FAULT,
    bk.O_LIMITS: LIMIT_FLAGS,
    bk.O_TRUE_TENSION: TRUE_TENSION,
    bk.O_TRUE_ELEVATION: TRUE_ELEVATION,
    bk.O_TRUE_VELOCITY: TRUE_ELEVATION_VELOCITY,
    bk.O_SHOULDER_TORQUE: SHOULDER_TORQUE,
    bk.O_STUCK: SHEATH_STUCK,
    bk.O_CORRECTION_TORQUE: CORRECTION_TORQUE,
    bk.O_COCONTRACTION: COCONTRACTION,
}


@dataclass(frozen=True, kw_only=True)
class ProtocolSettings:
    """How the paper's protocol is run.

    Parameters
    ----------
    conditions, speeds
        Which of ``contracts.CONDITIONS`` and ``contracts.SPEEDS`` to run.
    repetitions
        Raise-and-lower cycles per trial (paper: 10).
    control_period_s
        Controller period (paper's suit: 500 Hz).
    substeps
        Plant steps per control period (8 → 4 kHz).
    lead_in_s, tail_s
        Rest at the low point before the reference moves and after it stops.
    hand_load_kg, floor_tension_n, pretension_n
        Paper: 0.5 kg in the hand, 10 N floor and pretension.
    limits
        The controller's safety limits.
    compensation
        ``"paper"`` (the paper's lines and sigmoid) or ``"dynamic"`` (the model's dynamic
        compensation, :mod:`bowden.model.dynamic`; needs a version-2 model).
    """

    conditions: tuple[str, ...] = c.CONDITIONS
    speeds: tuple[str, ...] = c.SPEEDS
    repetitions: int = c.REPETITIONS_PER_TRIAL
    control_period_s: float = 0.002
    substeps: int = 8
    lead_in_s: float = 1.0
    tail_s: float = 0.5
    hand_load_kg: float = 0.5
    floor_tension_n: float = 10.0
    pretension_n: float = 10.0
    limits: ControllerLimits = field(default_factory=ControllerLimits)
    compensation: Literal["paper", "dynamic"] = "paper"

    def __post_init__(self) -> None:
        if self.compensation not in ("paper", "dynamic"):
            raise ParameterError(f"compensation must be 'paper' or 'dynamic', got {self.compensation!r}")
        for name in self.conditions:
            if name not in c.CONDITIONS:
                raise ParameterError(f"unknown condition {name!r}; known: {', '.join(c.CONDITIONS)}")
        for name in self.speeds:
            if name not in c.SPEEDS:
                raise ParameterError(f"unknown speed {name!r}; known: {', '.join(c.SPEEDS)}")
        if not 1 <= self.repetitions <= 100:
            raise ParameterError(f"repetitions must be in [1, 100], got {self.repetitions}")
        if not 1e-4 <= self.control_period_s <= 0.02:
            raise ParameterError(f"control_period_s must be in [1e-4, 0.02] s, got {self.control_period_s}")
        if not 1 <= self.substeps <= 100:
            raise ParameterError(f"substeps must be in [1, 100], got {self.substeps}")
        if self.control_period_s / self.substeps > 5e-4:
            raise ParameterError("control_period_s / substeps must be at most 0.5 ms (the plant's step)")
        if not (0.0 <= self.lead_in_s <= 10.0 and 0.0 <= self.tail_s <= 10.0):
            raise ParameterError("lead_in_s and tail_s must be in [0, 10] s")


def participant_suit(suit: SuitParameters, participant: VirtualParticipant) -> SuitParameters:
    """The suit as worn by ``participant``: its sheath friction scaled by the wearer's routing."""
    sheath = suit.sheath
    kinetic = min(sheath.kinetic_coefficient * participant.sheath_friction_scale, 0.5)
    kinetic = min(kinetic, 0.59 / sheath.static_to_kinetic_ratio)
    return replace(suit, sheath=replace(sheath, kinetic_coefficient=kinetic))


def trial_seed(seed: int, participant_index: int, condition: str, speed: str) -> int:
    """Seed of one trial, derived from the study seed so a trial can be re-run alone (resuming)."""
    ci, si = c.CONDITIONS.index(condition), c.SPEEDS.index(speed)
    return int(np.random.SeedSequence([seed, participant_index, ci, si]).generate_state(1)[0])


def simulate_trial(
    participant: VirtualParticipant,
    condition: str,
    speed: str,
    *,
    model: CompensationModel,
    suit: SuitParameters | None = None,
    settings: ProtocolSettings | None = None,
    seed: int = 0,
    session_trial: int = 0,
) -> TrialSimulation:
    """Simulate one trial (``repetitions`` cycles of the reference) of ``participant``.

    ``session_trial`` is the number of trials the participant did before this one in its session
    (:func:`session_trial`): practice shortens its lag (:meth:`VirtualParticipant.trial_lag_s`).
    """
    check_seed(seed)
    settings = settings if settings is not None else ProtocolSettings()
    if condition not in c.CONDITIONS:
        raise ParameterError(f"unknown condition {condition!r}; known: {', '.join(c.CONDITIONS)}")
    if speed not in c.SPEEDS:
        raise ParameterError(f"unknown speed {speed!r}; known: {', '.join(c.SPEEDS)}")
    worn = participant_suit(suit if suit is not None else SuitParameters(), participant)
    cycle = MinimumJerkCycle(
        low_rad=math.radians(c.ELEVATION_LOW_DEG),
        high_rad=math.radians(c.ELEVATION_HIGH_DEG),
        peak_speed_rad_s=math.radians(c.SPEED_PEAK_DEG_S[speed]),
    )
    support = c.CONDITION_SUPPORT[condition]
    wears_suit = support is not None
    controller, expected = _trial_controller(participant, support, worn, model, settings, speed)
    duration = settings.lead_in_s + settings.repetitions * cycle.period_s + settings.tail_s
    n_control = math.ceil(duration / settings.control_period_s)
    rng = np.random.default_rng(seed)
    draws_control = rng.standard_normal((n_control, 3))
    draws_human = rng.standard_normal((n_control * settings.substeps, 2))
    lag_s = participant.trial_lag_s(session_trial, float(rng.standard_normal()))
    h = human_vector(
        participant, cycle, cycles=settings.repetitions, start_s=settings.lead_in_s, expected=expected,
        lag_s=lag_s, excursion_draws=rng.standard_normal(settings.repetitions),
    )
    p = pack_parameters(worn, participant.arm_parameters())
    start_elevation = cycle.low_rad + participant.aim_offset_rad
    # The cable starts taut at what the controller holds at rest; the arm is balanced by the muscles.
    x = equilibrium_state(p, start_elevation, settings.pretension_n if wears_suit else 0.0)
    sensors = _sensor_vector(worn, settings)
    # The participant holds the start posture against gravity (and the cable) from the first step.
    x[k.X_ARM_THD] = 0.0
    out = np.empty((n_control, bk.N_OUT))
    bk.run_trial(
        x, p, h, bk.controller_vector(controller), bk.controller_state(controller), sensors, wears_suit,
        settings.control_period_s, settings.substeps, draws_control, draws_human, out,
    )
    # The motor's reply and the load cell at their real resolution (the IMU's is set in the kernel).
    out[:, bk.O_MOTOR_TORQUE] = ak60_torque(out[:, bk.O_MOTOR_TORQUE], MOTOR_REPLY_LIMITS)
    out[:, bk.O_MOTOR_VELOCITY] = ak60_velocity(out[:, bk.O_MOTOR_VELOCITY], MOTOR_REPLY_LIMITS)
    out[:, bk.O_TENSION] = load_cell_reading(out[:, bk.O_TENSION], worn.load_cell)
    signals = {name: np.ascontiguousarray(out[:, index]) for index, name in _OUTPUT_NAMES.items()}
    signals[c.TRIAL_STATE] = np.full(n_control, float(c.LOOP_STATE_RUNNING))  # no watchdog in a batch trial
    ordered = {name: signals[name] for name in (*c.TRIAL_COLUMNS[1:], LIMIT_FLAGS, *TRUTH_SIGNALS)}
    return TrialSimulation(
        participant=participant,
        condition=condition,
        speed=speed,
        time_s=np.asarray(np.arange(n_control) * settings.control_period_s, dtype=np.float64),
        signals=ordered,
        movement_start_s=settings.lead_in_s,
        movement_duration_s=cycle.movement_duration_s,
        repetitions=settings.repetitions,
        seed=seed,
    )


def _trial_controller(
    participant: VirtualParticipant, support: float | str | None, worn: SuitParameters,
    model: CompensationModel, settings: ProtocolSettings, speed: str,
) -> tuple[Controller | None, ExpectedAssistance | None]:
    """The controller of a condition with the suit and the assistance the participant expects from it
    (both None without the suit)."""
    if support is None:
        return None, None
    controller = build_controller(
        model=model,
        support="pretension" if support == "pretension" else float(support),
        subject=participant.subject,
        hand_load_kg=settings.hand_load_kg,
        geometry=worn.geometry,
        limits=settings.limits,
        floor_tension_n=settings.floor_tension_n,
        pretension_n=settings.pretension_n,
        compensation=settings.compensation,
        speed=speed,
    )
    expected = ExpectedAssistance.for_condition(
        support,
        participant.subject,
        hand_load_kg=settings.hand_load_kg,
        floor_tension_n=settings.floor_tension_n,
        pretension_n=settings.pretension_n,
    )
    return controller, expected


def _sensor_vector(worn: SuitParameters, settings: ProtocolSettings) -> NDArray[np.float64]:
    """The batch kernel's sensor parameters: the IMU's noise, bias and latency, the load cell's."""
    imu, cell = worn.imu, worn.load_cell
    sensors = np.zeros(bk.N_SENSOR)
    sensors[bk.S_IMU_EL_NOISE] = imu.elevation_noise_rad
    sensors[bk.S_IMU_EL_BIAS] = imu.elevation_bias_rad
    sensors[bk.S_IMU_VEL_NOISE] = imu.velocity_noise_rad_s
    sensors[bk.S_IMU_VEL_BIAS] = imu.velocity_bias_rad_s
    sensors[bk.S_LOAD_NOISE] = cell.noise_n
    sensors[bk.S_LOAD_OFFSET] = cell.offset_n
    sensors[bk.S_IMU_DELAY_CYCLES] = round(imu.latency_s / settings.control_period_s) * 1.0
    return sensors


def session_trial(order: Sequence[str], condition: str, speeds: Sequence[str], speed: str) -> int:
    """How many trials come before ``(condition, speed)`` in a session run in condition ``order``,
    each condition's speeds in the order of ``speeds`` (the paper: V1, V2, V3)."""
    try:
        return list(order).index(condition) * len(speeds) + list(speeds).index(speed)
    except ValueError:
        raise ParameterError(
            f"{condition}/{speed} is not in the session {list(order)} × {list(speeds)}"
        ) from None


def condition_order(seed: int, participant_index: int, conditions: Sequence[str]) -> tuple[str, ...]:
    """No suit first (baseline EMG), the other conditions shuffled (paper, Protocol)."""
    rng = np.random.default_rng([seed, participant_index, 99])
    first = [name for name in conditions if name == c.CONDITION_NO_SUIT]
    rest = [name for name in conditions if name != c.CONDITION_NO_SUIT]
    return tuple(first + [rest[i] for i in rng.permutation(len(rest))])


def simulate_cohort(
    participants: Sequence[VirtualParticipant],
    *,
    model: CompensationModel,
    suit: SuitParameters | None = None,
    settings: ProtocolSettings | None = None,
    seed: int = 0,
    progress: Callable[[int, int], None] | Literal[False] = False,
) -> CohortSimulation:
    """Simulate the protocol for every participant: trials, then questionnaire answers.

    ``progress(done, total)`` is called after each trial when given.
    """
    check_seed(seed)
    settings = settings if settings is not None else ProtocolSettings()
    if not participants:
        raise ParameterError("simulate_cohort needs at least one participant")
    trials: list[TrialSimulation] = []
    orders: dict[str, tuple[str, ...]] = {}
    total = len(participants) * len(settings.conditions) * len(settings.speeds)
    for index, participant in enumerate(participants):
        order = condition_order(seed, index, settings.conditions)
        orders[participant.participant_id] = order
        for condition in order:
            for speed in settings.speeds:
                trials.append(
                    simulate_trial(
                        participant, condition, speed, model=model, suit=suit, settings=settings,
                        seed=trial_seed(seed, index, condition, speed),
                        session_trial=session_trial(order, condition, settings.speeds, speed),
                    )
                )
                if progress:
                    progress(len(trials), total)
    answers = questionnaire_answers(trials, seed=seed)
    return CohortSimulation(
        participants=tuple(participants), trials=tuple(trials), condition_orders=orders,
        questionnaires=answers,
    )
