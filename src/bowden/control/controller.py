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
from operator import itemgetter
from pathlib import Path
from typing import Literal, NamedTuple, Protocol

from bowden.control.faults import Fault, Limit
from bowden.control.limits import ControllerLimits
from bowden.model.anthropometry import STANDARD_GRAVITY_M_S2, ArmModel, Subject, arm_model
from bowden.model.assistance import AssistanceParameters
from bowden.model.compensation import CompensationModel
from bowden.model.geometry import CuffGeometry

_NAN = math.nan
# Bound once: a module global is one lookup on the hot path, math.sin two.
_sin, _cos, _sqrt, _exp = math.sin, math.cos, math.sqrt, math.exp


class Command(tuple[float, float, float, int, int]):
    """One cycle's output, a 5-tuple with named fields.

    torque_nm
        Motor torque to command, Nm (spool side, ≥ 0; 0 on a fault).
    tension_n
        Desired cable tension at the arm anchor, N (NaN on a fault).
    moment_arm_m
        Cable moment arm r(θ) of this cycle, m (NaN on a fault).
    faults
        :class:`Fault` bits (0: none).
    limits
        :class:`Limit` bits: which limits shaped the command.

    Built on the hot path as ``Command((torque, tension, arm, faults, limits))``: tuple's own C
    constructor, about 40 % cheaper than a NamedTuple's Python ``__new__``. :meth:`of` takes keywords.
    """

    __slots__ = ()
    _fields = ("torque_nm", "tension_n", "moment_arm_m", "faults", "limits")

    torque_nm = property(itemgetter(0), doc="Motor torque to command, Nm.")
    tension_n = property(itemgetter(1), doc="Desired cable tension at the arm, N.")
    moment_arm_m = property(itemgetter(2), doc="Cable moment arm of this cycle, m.")
    faults = property(itemgetter(3), doc="Fault bits (0: none).")
    limits = property(itemgetter(4), doc="Limit bits.")

    @classmethod
    def of(
        cls, *, torque_nm: float, tension_n: float, moment_arm_m: float, faults: int = 0, limits: int = 0
    ) -> Command:
        """A command from keywords."""
        return cls((torque_nm, tension_n, moment_arm_m, faults, limits))

    def _asdict(self) -> dict[str, float | int]:
        return dict(zip(self._fields, self, strict=True))

    def __repr__(self) -> str:
        fields = ", ".join(f"{name}={value!r}" for name, value in zip(self._fields, self, strict=True))
        return f"Command({fields})"


_TENSION = int(Limit.TENSION)
_TORQUE = int(Limit.TORQUE)
_RATE = int(Limit.TORQUE_RATE)


class StepFunction(Protocol):
    """Signature of :attr:`Controller.step`."""

    def __call__(
        self,
        time_s: float,
        elevation_rad: float,
        elevation_velocity_rad_s: float,
        motor_velocity_rad_s: float = _NAN,
        motor_torque_nm: float = _NAN,
    ) -> Command: ...


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

    __slots__ = ("_state", "arm", "assistance", "geometry", "limits", "model", "step", "subject")

    def __init__(
        self,
        *,
        model: CompensationModel,
        subject: Subject,
        arm: ArmModel,
        geometry: CuffGeometry,
        assistance: AssistanceParameters,
        limits: ControllerLimits,
    ) -> None:
        self.model = model
        self.subject = subject
        self.arm = arm
        self.geometry = geometry
        self.assistance = assistance
        self.limits = limits
        self.step: StepFunction
        self._state: _StepState
        self.step, self._state = _compile_step(model, arm, geometry, assistance, limits)

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
    a, b = geometry.exit_distance_m, geometry.anchor_distance_m
    ab, aabb, two_ab = a * b, a * a + b * b, 2.0 * a * b
    psi = geometry.rest_angle_rad
    # support·g·Σmd turns τ_g(θ)·support into one multiply by sin θ; NaN pretension marks the law.
    if assistance.is_pretension:
        pretension, support_moment = assistance.pretension_n, 0.0
    else:
        pretension = _NAN
        support_moment = float(assistance.support) * STANDARD_GRAVITY_M_S2 * arm.total_moment_kg_m
    floor = assistance.floor_tension_n
    max_tension = limits.max_tension_n
    low_intercept, low_slope = model.lowering.intercept_nm, model.lowering.slope_m
    d_intercept = model.raising.intercept_nm - low_intercept
    d_slope = model.raising.slope_m - low_slope
    blend_mid, blend_steep = model.blend_midpoint_rad_s, model.blend_steepness_s_rad
    min_torque, max_torque = limits.min_torque_nm, limits.max_torque_nm
    max_rate, nominal_dt = limits.max_torque_rate_nm_s, limits.nominal_period_s
    elev_min = limits.elevation_min_rad
    elev_max = min(limits.elevation_max_rad, geometry.max_elevation_rad)
    max_vel = limits.max_elevation_velocity_rad_s
    min_vel = -max_vel
    max_motor_vel = limits.max_motor_velocity_rad_s
    min_motor_vel = -max_motor_vel
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
            return _fault_command(
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


def _fault_command(
    time_s: float,
    elevation_rad: float,
    elevation_velocity_rad_s: float,
    motor_velocity_rad_s: float,
    motor_torque_nm: float,
    elev_min: float,
    elev_max: float,
    max_vel: float,
    max_motor_vel: float,
) -> Command:
    """The safe command, with flags saying which input was wrong (off the hot path)."""
    faults = Fault.NONE
    if not all(math.isfinite(v) for v in (time_s, elevation_rad, elevation_velocity_rad_s)) or any(
        math.isinf(v) for v in (motor_velocity_rad_s, motor_torque_nm)
    ):
        faults |= Fault.NONFINITE_INPUT
    if math.isfinite(elevation_rad) and not elev_min <= elevation_rad <= elev_max:
        faults |= Fault.ELEVATION_OUT_OF_RANGE
    if math.isfinite(elevation_velocity_rad_s) and abs(elevation_velocity_rad_s) > max_vel:
        faults |= Fault.ELEVATION_VELOCITY_OUT_OF_RANGE
    if math.isfinite(motor_velocity_rad_s) and abs(motor_velocity_rad_s) > max_motor_vel:
        faults |= Fault.MOTOR_OVERSPEED
    return Command((0.0, _NAN, _NAN, int(faults), 0))


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

    Raises
    ------
    bowden.errors.ParameterError, bowden.errors.ModelFileError
        For invalid parameters or an unreadable model file.
    """
    compensation = model if isinstance(model, CompensationModel) else CompensationModel.load(model)
    return Controller(
        model=compensation,
        subject=subject,
        arm=arm_model(subject, hand_load_kg),
        geometry=geometry if geometry is not None else CuffGeometry(),
        assistance=AssistanceParameters(
            support=support, floor_tension_n=floor_tension_n, pretension_n=pretension_n
        ),
        limits=limits if limits is not None else ControllerLimits(),
    )
