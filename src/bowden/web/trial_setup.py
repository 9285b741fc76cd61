"""What the operator chooses for a trial, validated, and the controller it implies.

The operator console sends participant, condition, speed, support, repetitions and the wearer's
anthropometrics (the controller's gravity model needs them; they are not identifying). The support is
the condition's and the reference's peak the speed's (the protocol's :class:`Catalogue`: the paper's
names and a lab's own), the rule ``bowden run`` applies too: a support that contradicts the condition
is refused, so no trial is stored under a condition it did not run in.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final, Literal

from bowden.contracts import (
    ELEVATION_HIGH_DEG,
    ELEVATION_LOW_DEG,
    REPETITIONS_PER_TRIAL,
    SPEED_PEAK_DEG_S,
)
from bowden.control import Command, build_controller
from bowden.errors import ParameterError, RequestError
from bowden.model import CompensationModel, Subject
from bowden.protocol.catalogue import PAPER, Catalogue
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.runtime.loop import StepController
from bowden.web.reference import TrialReference
from bowden.web.validation import choice, integer_in, no_unknown_fields, number_in, participant_id

TAIL_S: Final = 1.0  # the loop runs this long after the last repetition (the arm comes to rest)
_FIELDS: Final = (
    "participant", "condition", "speed", "support", "repetitions", "lead_in_s",
    "height_m", "mass_kg", "sex", "hand_load_kg",
)


@dataclass(frozen=True, kw_only=True)
class TrialSetup:
    """One trial as the operator chose it.

    Parameters
    ----------
    participant
        Pseudonymous id (``P01``).
    condition, speed
        Names of the protocol's catalogue (``contracts.CONDITIONS`` and ``contracts.SPEEDS``, or a
        lab's own).
    support
        Gravity-support fraction, ``"pretension"``, or None (no suit): the condition's.
    repetitions
        Raise-and-lower cycles (paper: 10).
    lead_in_s
        Rest before the reference starts moving, s.
    subject
        The wearer's anthropometrics (controller gravity model).
    hand_load_kg
        Weight held in the hand (paper: 0.5 kg).
    speed_peak_deg_s
        The reference's peak elevation speed, °/s; None: the paper's speed's (a paper speed with
        another peak is refused).
    """

    participant: str
    condition: str
    speed: str
    support: float | Literal["pretension"] | None
    repetitions: int = REPETITIONS_PER_TRIAL
    lead_in_s: float = 2.0
    subject: Subject
    hand_load_kg: float = 0.5
    speed_peak_deg_s: float | None = None

    def __post_init__(self) -> None:
        paper = SPEED_PEAK_DEG_S.get(self.speed)
        if self.speed_peak_deg_s is None:
            if paper is None:
                raise ParameterError(f"speed {self.speed}: not the paper's, give its peak (speed_peak_deg_s)")
            object.__setattr__(self, "speed_peak_deg_s", paper)
        elif paper is not None and not math.isclose(self.speed_peak_deg_s, paper, rel_tol=1e-9):
            raise ParameterError(
                f"speed {self.speed} is the paper's {paper:g} °/s, not {self.speed_peak_deg_s:g}"
            )

    @property
    def reference(self) -> TrialReference:
        """The minimum-jerk reference shown during this trial."""
        return study_reference(self.speed, lead_in_s=self.lead_in_s, repetitions=self.repetitions,
                               peak_deg_s=self.speed_peak_deg_s)

    @property
    def duration_s(self) -> float:
        """How long the loop runs: lead-in, the repetitions, and a short rest."""
        return self.reference.end_s + TAIL_S

    @property
    def recorded_support(self) -> float | None:
        """The ``support`` column of the trials table (NULL for pretension and no suit)."""
        return self.support if isinstance(self.support, float) else None

    def to_json(self) -> dict[str, object]:
        return {
            "participant": self.participant,
            "condition": self.condition,
            "speed": self.speed,
            "support": self.support,
            "repetitions": self.repetitions,
            "lead_in_s": self.lead_in_s,
            "height_m": self.subject.height_m,
            "mass_kg": self.subject.mass_kg,
            "sex": self.subject.sex,
            "hand_load_kg": self.hand_load_kg,
            "speed_peak_deg_s": self.speed_peak_deg_s,
        }


def study_reference(
    speed: str, *, lead_in_s: float, repetitions: int, peak_deg_s: float | None = None
) -> TrialReference:
    """The study's reference at ``speed``: rest, ``repetitions`` cycles between the study's elevations.

    ``peak_deg_s``: the speed's peak elevation speed, °/s (None: the paper's speed's).
    """
    peak = SPEED_PEAK_DEG_S[speed] if peak_deg_s is None else peak_deg_s
    cycle = MinimumJerkCycle(
        low_rad=math.radians(ELEVATION_LOW_DEG),
        high_rad=math.radians(ELEVATION_HIGH_DEG),
        peak_speed_rad_s=math.radians(peak),
    )
    return TrialReference(cycle=cycle, start_s=lead_in_s, repetitions=repetitions)


def condition_support(condition: str, catalogue: Catalogue = PAPER) -> float | Literal["pretension"] | None:
    """The support a condition stands for (the catalogue's): the one rule of serve and run."""
    return catalogue.support(condition)


def parse_setup(payload: Mapping[str, object], catalogue: Catalogue = PAPER) -> TrialSetup:
    """Validate the console's start request (conditions and speeds of ``catalogue``).

    Raises
    ------
    RequestError
        Naming the first missing, unknown or out-of-range field.
    """
    data = dict(payload)
    data.pop("token", None)
    no_unknown_fields(data, _FIELDS, "trial")
    for required in ("participant", "condition", "speed", "height_m", "mass_kg", "sex"):
        if required not in data:
            raise RequestError(f"trial: the field {required!r} is missing")
    condition = choice(data["condition"], catalogue.condition_names, "condition")
    support = condition_support(condition, catalogue)
    raw_support = data.get("support")
    if raw_support not in (None, ""):
        if not isinstance(support, float):
            raise RequestError(f"support: the {condition} condition has no support fraction to set")
        if number_in(raw_support, 0.0, 1.0, "support") != support:
            # One rule with bowden run: a trial is stored under the condition it ran in.
            raise RequestError(
                f"support: {condition} means support {support}; a trial runs its condition's support"
            )
    speed = choice(data["speed"], catalogue.speed_names, "speed")
    sex = choice(data["sex"], ("female", "male"), "sex")
    subject = Subject(
        height_m=number_in(data["height_m"], 1.0, 2.3, "height_m"),
        mass_kg=number_in(data["mass_kg"], 25.0, 250.0, "mass_kg"),
        sex="female" if sex == "female" else "male",
    )
    return TrialSetup(
        participant=participant_id(data["participant"]),
        condition=condition,
        speed=speed,
        speed_peak_deg_s=catalogue.peak_deg_s(speed),
        support=support,
        repetitions=integer_in(data.get("repetitions", REPETITIONS_PER_TRIAL), 1, 30, "repetitions"),
        lead_in_s=number_in(data.get("lead_in_s", 2.0), 0.0, 10.0, "lead_in_s"),
        subject=subject,
        hand_load_kg=number_in(data.get("hand_load_kg", 0.5), 0.0, 5.0, "hand_load_kg"),
    )


class NoAssistance:
    """The controller of the "no suit" condition: zero torque, no desired tension.

    The loop still runs (the display needs the elevation, the recording its samples), but the
    cable is not driven.
    """

    _ZERO: Final = Command.of(torque_nm=0.0, tension_n=math.nan, moment_arm_m=math.nan, faults=0, limits=0)

    def step(
        self,
        time_s: float,
        elevation_rad: float,
        elevation_velocity_rad_s: float,
        motor_velocity_rad_s: float = math.nan,
        motor_torque_nm: float = math.nan,
    ) -> Command:
        return self._ZERO


def controller_for(setup: TrialSetup, model: CompensationModel) -> StepController:
    """The controller of ``setup``'s condition on the suit described by ``model``."""
    if setup.support is None:
        return NoAssistance()
    return build_controller(
        model=model, support=setup.support, subject=setup.subject, hand_load_kg=setup.hand_load_kg,
        speed=setup.speed,
    )


def tension_estimate_n(
    model: CompensationModel, motor_torque_nm: float, elevation_velocity_rad_s: float
) -> float:
    """Cable tension at the arm implied by the measured motor torque: the model solved for tension.

    The model's torque is linear in tension for a given velocity, τ = a(w) + b(w)·T with
    a(w), b(w) the blend of the two lines' intercepts and slopes, so T = (τ − a(w)) / b(w). This is
    the sensorless estimate the console plots against the desired tension.
    """
    w = model.blend_weight(elevation_velocity_rad_s)
    raising, lowering = model.raising, model.lowering
    intercept = lowering.intercept_nm + (raising.intercept_nm - lowering.intercept_nm) * w
    slope = lowering.slope_m + (raising.slope_m - lowering.slope_m) * w
    return (motor_torque_nm - intercept) / slope
