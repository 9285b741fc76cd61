"""The sensorless tension controller: gravity assistance → inverse transmission model → limits.

One :meth:`Controller.step` per control cycle, shared by the hardware loop, the simulated suit and
any outside check. It is the hot path: plain floats, constants folded at construction, no numpy, no
logging, nothing allocated but the returned :class:`Command`. It never raises on bad input; it returns
the safe command (zero torque) with fault flags instead.

Each cycle (paper, "Control architecture"):

1. desired tension T = max(T_floor, support·τ_g(θ)/r(θ)) or the constant pretension, clamped to the
   maximum tension (:mod:`bowden.model.assistance`);
2. motor torque τ = τ_low(T) + (τ_raise(T) − τ_low(T))·w(θ̇) from the compensation model
   (:mod:`bowden.model.compensation`);
3. τ clamped to the motor's range (never below zero: a cable cannot push) and rate-limited.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Literal, NamedTuple

from bowden.control.command import Command, StepFunction, fault_command
from bowden.control.dynamic_step import compile_dynamic_step
from bowden.control.faults import Limit
from bowden.control.folding import fold
from bowden.control.limits import ControllerLimits
from bowden.errors import ParameterError
from bowden.model.anthropometry import ArmModel, Subject, arm_model
from bowden.model.assistance import AssistanceParameters
from bowden.model.compensation import CompensationModel
from bowden.model.geometry import CuffGeometry
from bowden.model.model_file import load_model

_NAN = math.nan
# Bound once: a module global is one lookup on the hot path, math.sin two.
_sin, _cos, _sqrt, _exp = math.sin, math.cos, math.sqrt, math.exp
_TENSION = int(Limit.TENSION)
_TORQUE = int(Limit.TORQUE)
_RATE = int(Limit.TORQUE_RATE)


class Controller:
    """The paper's controller for one wearer, support level, suit model and set of limits.

    Build it with :func:`build_controller`. The parameters it was built from are kept as read-only
    attributes (``model``, ``subject``, ``arm``, ``geometry``, ``assistance``, ``limits``); the
    cycle-to-cycle state is only the last commanded torque and time (for the rate limit).

    ``step(time_s, elevation_rad, elevation_velocity_rad_s, motor_velocity_rad_s=nan,
    motor_torque_nm=nan) -> Command`` computes one cycle:

    time_s
        Time of the cycle, s (monotonic; used by the torque-rate limit).
    elevation_rad, elevation_velocity_rad_s
        Humeral elevation (0 = arm hanging) and its velocity (> 0 raising).
    motor_velocity_rad_s, motor_torque_nm
        Latest motor readings, if known (NaN: unknown); checked for plausibility only.

    ``step`` is a closure compiled at construction with every constant folded into it: on CPython a
    closure variable is a cheaper load than an attribute, which keeps the checks and the named result
    within the cost budget of the arithmetic itself (see ``benchmarks/controller.py``).
    """

    __slots__ = (
        "_state", "arm", "assistance", "compensation", "geometry", "limits", "model", "step", "subject",
    )

    def __init__(
        self,
        *,
        model: CompensationModel,
        subject: Subject,
        arm: ArmModel,
        geometry: CuffGeometry,
        assistance: AssistanceParameters,
        limits: ControllerLimits,
        compensation: Literal["paper", "dynamic"] = "paper",
    ) -> None:
        self.model = model
        self.compensation = compensation
        self.subject = subject
        self.arm = arm
        self.geometry = geometry
        self.assistance = assistance
        self.limits = limits
        self.step: StepFunction
        self._state: _StepState
        if compensation == "paper":
            self.step, self._state = _compile_step(model, arm, geometry, assistance, limits)
        elif compensation == "dynamic" and model.dynamic is not None:
            step, reset, torque_nm = compile_dynamic_step(
                model.dynamic, model.pulley_radius_m, arm, geometry, assistance, limits
            )
            self.step, self._state = step, _StepState(reset=reset, torque_nm=torque_nm)
        elif compensation == "dynamic":
            raise ParameterError(
                "compensation 'dynamic' needs a model with its dynamic part (model.json version 2, written "
                "by bowden identify); this model holds the paper's lines only"
            )
        else:
            raise ParameterError(f"compensation must be 'paper' or 'dynamic', got {compensation!r}")

    def reset(self) -> None:
        """Forget the last command: the next torque ramps up from zero again."""
        self._state.reset()

    @property
    def last_torque_nm(self) -> float:
        """The torque of the last command (0 after a fault or reset)."""
        return self._state.torque_nm()


class _StepState(NamedTuple):
    """Access to the closure's state from outside the hot path."""

    reset: Callable[[], None]
    torque_nm: Callable[[], float]


def _compile_step(
    model: CompensationModel,
    arm: ArmModel,
    geometry: CuffGeometry,
    assistance: AssistanceParameters,
    limits: ControllerLimits,
) -> tuple[StepFunction, _StepState]:
    """Fold every constant into a step closure; return it with accessors of its state."""
    (
        ab, aabb, two_ab, psi, pretension, support_moment, floor, max_tension,
        min_torque, max_torque, max_rate, nominal_dt, elev_min, elev_max, max_vel, max_motor_vel,
    ) = fold(arm, geometry, assistance, limits)
    min_vel, min_motor_vel = -max_vel, -max_motor_vel
    low_intercept, low_slope = model.lowering.intercept_nm, model.lowering.slope_m
    d_intercept = model.raising.intercept_nm - low_intercept
    d_slope = model.raising.slope_m - low_slope
    blend_mid, blend_steep = model.blend_midpoint_rad_s, model.blend_steepness_s_rad
    last_torque = 0.0
    last_time = _NAN

    def step(
        time_s: float,
        elevation_rad: float,
        elevation_velocity_rad_s: float,
        motor_velocity_rad_s: float = _NAN,
        motor_torque_nm: float = _NAN,
    ) -> Command:
        nonlocal last_torque, last_time
        # Chained comparisons: NaN fails every one of them, so range checks also reject NaN; x − x is
        # 0 only for finite x. NaN motor readings mean "unknown" and pass.
        if not (
            elev_min <= elevation_rad <= elev_max
            and min_vel <= elevation_velocity_rad_s <= max_vel
            and time_s - time_s == 0.0
        ) or (
            motor_velocity_rad_s == motor_velocity_rad_s
            and not min_motor_vel <= motor_velocity_rad_s <= max_motor_vel
        ) or (motor_torque_nm == motor_torque_nm and motor_torque_nm - motor_torque_nm != 0.0):
            last_torque, last_time = 0.0, _NAN
            return fault_command(
                time_s, elevation_rad, elevation_velocity_rad_s, motor_velocity_rad_s, motor_torque_nm,
                elev_min, elev_max, max_vel, max_motor_vel,
            )

        alpha = psi - elevation_rad
        moment_arm = ab * _sin(alpha) / _sqrt(aabb - two_ab * _cos(alpha))
        limited = 0
        tension = pretension
        if tension != tension:  # support law
            tension = floor
            if moment_arm > 0.0:
                supported = support_moment * _sin(elevation_rad) / moment_arm
                if supported > tension:
                    tension = supported
        if tension > max_tension:
            tension = max_tension
            limited = _TENSION

        x = blend_steep * (elevation_velocity_rad_s - blend_mid)
        if x >= 0.0:  # two branches so exp never overflows
            weight = 1.0 / (1.0 + _exp(-x))
        else:
            e = _exp(x)
            weight = e / (1.0 + e)
        torque = low_intercept + low_slope * tension + (d_intercept + d_slope * tension) * weight

        if torque > max_torque:
            torque = max_torque
            limited |= _TORQUE
        elif torque < min_torque:
            torque = min_torque
            limited |= _TORQUE

        dt = time_s - last_time
        if not 0.0 < dt < 0.1:  # first cycle, repeated time or a stall: assume one nominal period
            dt = nominal_dt
        step_max = max_rate * dt
        if torque > last_torque + step_max:
            torque = last_torque + step_max
            limited |= _RATE
        elif torque < last_torque - step_max:
            torque = last_torque - step_max
            limited |= _RATE
        last_torque, last_time = torque, time_s
        return Command((torque, tension, moment_arm, 0, limited))

    def reset() -> None:
        nonlocal last_torque, last_time
        last_torque, last_time = 0.0, _NAN

    def torque_nm() -> float:
        return last_torque

    return step, _StepState(reset=reset, torque_nm=torque_nm)


def build_controller(
    *,
    model: CompensationModel | str | Path,
    support: float | Literal["pretension"],
    subject: Subject,
    hand_load_kg: float = 0.5,
    geometry: CuffGeometry | None = None,
    limits: ControllerLimits | None = None,
    floor_tension_n: float = 10.0,
    pretension_n: float = 10.0,
    compensation: Literal["paper", "dynamic"] | None = None,
) -> Controller:
    """Build the controller for one wearer and condition.

    Parameters
    ----------
    model
        A :class:`CompensationModel` or the path of its ``model.json``.
    support
        Fraction of the gravitational shoulder torque to support (0–1), or ``"pretension"``.
    subject
        The wearer's anthropometrics.
    hand_load_kg
        Load held in the hand, kg (paper: 0.5).
    geometry, limits
        Cuff geometry and safety limits; defaults reproduce the paper's suit.
    floor_tension_n, pretension_n
        Floor under the support law and the constant pretension, N (paper: 10 N).
    compensation
        ``"paper"``: the paper's two lines and sigmoid, exactly; ``"dynamic"``: the model's dynamic
        compensation (:mod:`bowden.model.dynamic`); None: the model's recommendation (dynamic when
        the model holds one).

    Raises
    ------
    bowden.errors.ParameterError, bowden.errors.ModelFileError
        For invalid parameters or an unreadable model file.
    """
    loaded = model if isinstance(model, CompensationModel) else load_model(model)
    if compensation is None:
        compensation = "dynamic" if loaded.dynamic is not None else "paper"
    return Controller(
        model=loaded,
        compensation=compensation,
        subject=subject,
        arm=arm_model(subject, hand_load_kg),
        geometry=geometry if geometry is not None else CuffGeometry(),
        assistance=AssistanceParameters(
            support=support, floor_tension_n=floor_tension_n, pretension_n=pretension_n
        ),
        limits=limits if limits is not None else ControllerLimits(),
    )
