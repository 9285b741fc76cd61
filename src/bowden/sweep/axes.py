"""The parameters a sweep can vary, and how each one reaches the controller or the simulated plant.

Two kinds of axis:

* **controller** — the blend of the two compensation lines (paper, "Control architecture"): the
  elevation velocities where the raising line has 1 % and 99 % weight, or the same blend as a width
  (``θ̇₀₉₉ − θ̇₀₀₁``) and a centre (``(θ̇₀₀₁ + θ̇₀₉₉)/2``, the sigmoid's midpoint M). Changing them
  changes the controller only; the identified lines stay.
* **plant** — fields of :class:`bowden.sim.SuitParameters`: the suit itself (sheath friction and
  viscous drag, the motor's true torque constant, its Coulomb friction, the IMU's latency). The
  simulator's own dataclasses validate the values, so a value outside a field's documented range is
  refused with that field's message.

A point's values are a mapping ``axis name → value``; axes that are not swept keep the paper's
blend (−1, +1 rad/s) and the simulator's defaults.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Literal

from bowden.errors import ParameterError
from bowden.sim.parameters import SuitParameters

BLEND_01 = "blend_velocity_01_rad_s"
BLEND_99 = "blend_velocity_99_rad_s"
BLEND_WIDTH = "blend_width_rad_s"
BLEND_CENTER = "blend_center_rad_s"
SHEATH_KINETIC = "sheath_kinetic_coefficient"
SHEATH_STATIC_RATIO = "sheath_static_to_kinetic_ratio"
SHEATH_VISCOUS = "sheath_viscous_coefficient_ns_m"
TORQUE_CONSTANT_RATIO = "torque_constant_ratio"
MOTOR_COULOMB = "motor_coulomb_friction_nm"
IMU_LATENCY = "imu_latency_s"

# The paper's blend (Control architecture: −1 and +1 rad/s).
PAPER_BLEND_01_RAD_S = -1.0
PAPER_BLEND_99_RAD_S = 1.0
# A blend velocity beyond this is far outside any arm movement (the study's fastest peak is π rad/s).
_BLEND_LIMIT_RAD_S = 20.0


@dataclass(frozen=True)
class Axis:
    """One sweepable parameter: its name (with unit), what it acts on and what it means."""

    name: str
    kind: Literal["controller", "plant"]
    description: str


AXES: dict[str, Axis] = {
    axis.name: axis
    for axis in (
        Axis(BLEND_01, "controller", "elevation velocity where the raising line has 1 % weight (paper −1)"),
        Axis(BLEND_99, "controller", "elevation velocity where the raising line has 99 % weight (paper +1)"),
        Axis(BLEND_WIDTH, "controller", "blend width θ̇₀₉₉ − θ̇₀₀₁, rad/s (paper 2); with blend_center_rad_s"),
        Axis(BLEND_CENTER, "controller", "blend centre (θ̇₀₀₁ + θ̇₀₉₉)/2, rad/s (paper 0)"),
        Axis(SHEATH_KINETIC, "plant", "sheath friction k = μ_k·sin(φ/2) (SheathParameters)"),
        Axis(SHEATH_STATIC_RATIO, "plant", "sheath breakaway / kinetic friction (static_to_kinetic_ratio)"),
        Axis(SHEATH_VISCOUS, "plant", "viscous drag of the cable in the sheath, N·s/m (SheathParameters)"),
        Axis(TORQUE_CONSTANT_RATIO, "plant", "true / assumed motor torque constant (MotorParameters)"),
        Axis(MOTOR_COULOMB, "plant", "motor and gearbox Coulomb friction, Nm (MotorParameters)"),
        Axis(IMU_LATENCY, "plant", "age of the IMU sample when the controller uses it, s (ImuParameters)"),
    )
}

# Plant axis → (part of SuitParameters, field of that part).
_PLANT_FIELDS: dict[str, tuple[str, str]] = {
    SHEATH_KINETIC: ("sheath", "kinetic_coefficient"),
    SHEATH_STATIC_RATIO: ("sheath", "static_to_kinetic_ratio"),
    SHEATH_VISCOUS: ("sheath", "viscous_coefficient_ns_m"),
    TORQUE_CONSTANT_RATIO: ("motor", "torque_constant_ratio"),
    MOTOR_COULOMB: ("motor", "coulomb_friction_nm"),
    IMU_LATENCY: ("imu", "latency_s"),
}
PLANT_AXES = tuple(_PLANT_FIELDS)
BLEND_AXES = (BLEND_01, BLEND_99, BLEND_WIDTH, BLEND_CENTER)


def check_axis_name(name: str) -> Axis:
    """The :class:`Axis` called ``name``; a :class:`ParameterError` listing the known ones otherwise."""
    axis = AXES.get(name)
    if axis is None:
        raise ParameterError(f"unknown sweep axis {name!r}; known axes: {', '.join(AXES)}")
    return axis


def check_axis_names(names: tuple[str, ...]) -> None:
    """Each name known, none twice, and the blend given one way only (01/99 or width/centre)."""
    for name in names:
        check_axis_name(name)
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise ParameterError(f"sweep axis {twice[0]!r} is given twice")
    velocities = {BLEND_01, BLEND_99} & set(names)
    shape = {BLEND_WIDTH, BLEND_CENTER} & set(names)
    if velocities and shape:
        raise ParameterError(
            f"sweep axes {sorted(velocities)[0]!r} and {sorted(shape)[0]!r} both set the blend: give "
            f"{BLEND_01}/{BLEND_99} or {BLEND_WIDTH}/{BLEND_CENTER}, not both"
        )


def check_blend_value(name: str, value: float) -> None:
    """Range of one blend-axis value (the width must be positive)."""
    if not math.isfinite(value) or abs(value) > _BLEND_LIMIT_RAD_S:
        raise ParameterError(
            f"{name} = {value!r} must be a finite velocity within ±{_BLEND_LIMIT_RAD_S} rad/s"
        )
    if name == BLEND_WIDTH and not value > 0.0:
        raise ParameterError(f"{name} = {value!r} must be positive (θ̇₀₉₉ must exceed θ̇₀₀₁)")


def blend_velocities(values: Mapping[str, float]) -> tuple[float, float]:
    """The blend ``(θ̇₀₀₁, θ̇₀₉₉)`` in rad/s of a point, the paper's −1/+1 where not swept."""
    if BLEND_WIDTH in values or BLEND_CENTER in values:
        width = values.get(BLEND_WIDTH, PAPER_BLEND_99_RAD_S - PAPER_BLEND_01_RAD_S)
        center = values.get(BLEND_CENTER, 0.5 * (PAPER_BLEND_01_RAD_S + PAPER_BLEND_99_RAD_S))
        return center - 0.5 * width, center + 0.5 * width
    return values.get(BLEND_01, PAPER_BLEND_01_RAD_S), values.get(BLEND_99, PAPER_BLEND_99_RAD_S)


def apply_plant(suit: SuitParameters, values: Mapping[str, float]) -> SuitParameters:
    """``suit`` with the point's plant axes set; the simulator's validation names a bad value's axis."""
    for name in PLANT_AXES:
        if name not in values:
            continue
        part_name, field_name = _PLANT_FIELDS[name]
        value = values[name]
        try:
            part = replace(getattr(suit, part_name), **{field_name: value})
            suit = replace(suit, **{part_name: part})
        except ParameterError as exc:
            raise ParameterError(f"sweep axis {name} = {value!r}: {exc}") from None
    return suit


def plant_values(suit: SuitParameters) -> dict[str, float]:
    """The effective value of every plant axis in ``suit``."""
    return {
        name: float(getattr(getattr(suit, part), field)) for name, (part, field) in _PLANT_FIELDS.items()
    }
