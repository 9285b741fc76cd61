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
from pathlib import Path
from typing import Literal, NamedTuple

from bowden.control.faults import Fault, Limit
from bowden.control.limits import ControllerLimits
from bowden.model.anthropometry import STANDARD_GRAVITY_M_S2, ArmModel, Subject, arm_model
from bowden.model.assistance import AssistanceParameters
from bowden.model.compensation import CompensationModel
from bowden.model.geometry import CuffGeometry

_NAN = math.nan
_INF = math.inf


class Command(NamedTuple):
    """One cycle's output.

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
    """

    torque_nm: float
    tension_n: float
    moment_arm_m: float
    faults: int
    limits: int


_new_command = tuple.__new__
_TENSION = int(Limit.TENSION)
_TORQUE = int(Limit.TORQUE)
_RATE = int(Limit.TORQUE_RATE)


class Controller:
    """The paper's controller for one wearer, support level, suit model and set of limits.

    Build it with :func:`build_controller`. The parameters it was built from are kept as read-only
    attributes (``model``, ``subject``, ``arm``, ``geometry``, ``assistance``, ``limits``); the
    cycle-to-cycle state is only the last commanded torque and time (for the rate limit).
    """

    __slots__ = (
        "_aabb",
        "_ab",
        "_blend_mid",
        "_blend_steep",
        "_d_intercept",
        "_d_slope",
        "_elev_max",
        "_elev_min",
        "_floor",
        "_last_time",
        "_low_intercept",
        "_low_slope",
        "_max_motor_vel",
        "_max_rate",
        "_max_tension",
        "_max_torque",
        "_max_vel",
        "_min_torque",
        "_nominal_dt",
        "_pretension",
        "_psi",
        "_support_moment",
        "_torque",
        "arm",
        "assistance",
        "geometry",
        "limits",
        "model",
        "subject",
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
    ) -> None:
        self.model = model
        self.subject = subject
        self.arm = arm
        self.geometry = geometry
        self.assistance = assistance
        self.limits = limits
        a, b = geometry.exit_distance_m, geometry.anchor_distance_m
        self._ab = a * b
        self._aabb = a * a + b * b
        self._psi = geometry.rest_angle_rad
        # support·g·Σmd folds τ_g(θ)·support into one multiply by sin θ.
        if assistance.is_pretension:
            self._pretension = assistance.pretension_n
            self._support_moment = 0.0
        else:
            self._pretension = _NAN
            self._support_moment = float(assistance.support) * STANDARD_GRAVITY_M_S2 * arm.total_moment_kg_m
        self._floor = assistance.floor_tension_n
        self._max_tension = limits.max_tension_n
        self._low_intercept = model.lowering.intercept_nm
        self._low_slope = model.lowering.slope_m
        self._d_intercept = model.raising.intercept_nm - model.lowering.intercept_nm
        self._d_slope = model.raising.slope_m - model.lowering.slope_m
        self._blend_mid = model.blend_midpoint_rad_s
        self._blend_steep = model.blend_steepness_s_rad
        self._min_torque = limits.min_torque_nm
        self._max_torque = limits.max_torque_nm
        self._max_rate = limits.max_torque_rate_nm_s
        self._nominal_dt = limits.nominal_period_s
        self._elev_min = limits.elevation_min_rad
        self._elev_max = min(limits.elevation_max_rad, geometry.max_elevation_rad)
        self._max_vel = limits.max_elevation_velocity_rad_s
        self._max_motor_vel = limits.max_motor_velocity_rad_s
        self._torque = 0.0
        self._last_time = _NAN

    def reset(self) -> None:
        """Forget the last command: the next torque ramps up from zero again."""
        self._torque = 0.0
        self._last_time = _NAN

    @property
    def last_torque_nm(self) -> float:
        """The torque of the last command (0 after a fault or reset)."""
        return self._torque

    def step(
        self,
        time_s: float,
        elevation_rad: float,
        elevation_velocity_rad_s: float,
        motor_velocity_rad_s: float = _NAN,
        motor_torque_nm: float = _NAN,
    ) -> Command:
        """Compute this cycle's motor torque.

        Parameters
        ----------
        time_s
            Time of the cycle, s (monotonic; used by the torque-rate limit).
        elevation_rad, elevation_velocity_rad_s
            Humeral elevation (0 = arm hanging) and its velocity (> 0 raising).
        motor_velocity_rad_s, motor_torque_nm
            Latest motor readings, if known (NaN: unknown). Checked for plausibility only.
        """
        # One chained comparison per input: NaN fails every comparison, so this also rejects NaN.
        if not (
            self._elev_min <= elevation_rad <= self._elev_max
            and -self._max_vel <= elevation_velocity_rad_s <= self._max_vel
            and -_INF < time_s < _INF
            and (motor_velocity_rad_s != motor_velocity_rad_s
                 or -self._max_motor_vel <= motor_velocity_rad_s <= self._max_motor_vel)
            and (motor_torque_nm != motor_torque_nm or -_INF < motor_torque_nm < _INF)
        ):
            return self._fault(
                time_s, elevation_rad, elevation_velocity_rad_s, motor_velocity_rad_s, motor_torque_nm
            )

        alpha = self._psi - elevation_rad
        moment_arm = self._ab * math.sin(alpha) / math.sqrt(self._aabb - 2.0 * self._ab * math.cos(alpha))
        limits = 0
        tension = self._pretension
        if tension != tension:  # support law (NaN pretension marks it)
            tension = self._floor
            if moment_arm > 0.0:
                supported = self._support_moment * math.sin(elevation_rad) / moment_arm
                if supported > tension:
                    tension = supported
        if tension > self._max_tension:
            tension = self._max_tension
            limits = _TENSION

        x = self._blend_steep * (elevation_velocity_rad_s - self._blend_mid)
        if x >= 0.0:
            weight = 1.0 / (1.0 + math.exp(-x))
        else:
            e = math.exp(x)
            weight = e / (1.0 + e)
        torque = self._low_intercept + self._low_slope * tension + (
            self._d_intercept + self._d_slope * tension
        ) * weight

        if torque > self._max_torque:
            torque = self._max_torque
            limits |= _TORQUE
        elif torque < self._min_torque:
            torque = self._min_torque
            limits |= _TORQUE

        dt = time_s - self._last_time
        if not 0.0 < dt < 0.1:  # first cycle, repeated time or a stall: assume one nominal period
            dt = self._nominal_dt
        previous = self._torque
        step_max = self._max_rate * dt
        if torque > previous + step_max:
            torque = previous + step_max
            limits |= _RATE
        elif torque < previous - step_max:
            torque = previous - step_max
            limits |= _RATE
        self._torque = torque
        self._last_time = time_s
        return _new_command(Command, (torque, tension, moment_arm, 0, limits))

    def _fault(
        self,
        time_s: float,
        elevation_rad: float,
        elevation_velocity_rad_s: float,
        motor_velocity_rad_s: float,
        motor_torque_nm: float,
    ) -> Command:
        """The safe command, with flags saying which input was wrong (off the hot path)."""
        faults = Fault.NONE
        if not all(math.isfinite(v) for v in (time_s, elevation_rad, elevation_velocity_rad_s)) or any(
            math.isinf(v) for v in (motor_velocity_rad_s, motor_torque_nm)
        ):
            faults |= Fault.NONFINITE_INPUT
        if math.isfinite(elevation_rad) and not self._elev_min <= elevation_rad <= self._elev_max:
            faults |= Fault.ELEVATION_OUT_OF_RANGE
        if math.isfinite(elevation_velocity_rad_s) and abs(elevation_velocity_rad_s) > self._max_vel:
            faults |= Fault.ELEVATION_VELOCITY_OUT_OF_RANGE
        if math.isfinite(motor_velocity_rad_s) and abs(motor_velocity_rad_s) > self._max_motor_vel:
            faults |= Fault.MOTOR_OVERSPEED
        self._torque = 0.0
        self._last_time = _NAN
        return _new_command(Command, (0.0, _NAN, _NAN, int(faults), 0))


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
