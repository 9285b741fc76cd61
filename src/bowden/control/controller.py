"""The sensorless tension controller for one wearer and condition, and how to build it.

One :meth:`Controller.step` per control cycle, shared by the hardware loop, the simulated suit and
any outside check. It is the hot path: plain floats, constants folded at construction, no numpy, no
logging, nothing allocated but the returned :class:`Command`. It never raises on bad input; it returns
the safe command (zero torque) with fault flags instead. Its arithmetic: :mod:`bowden.control.step`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from bowden.control.command import StepFunction
from bowden.control.limits import ControllerLimits
from bowden.control.step import compile_step
from bowden.errors import ParameterError
from bowden.model.anthropometry import ArmModel, Subject, arm_model
from bowden.model.assistance import AssistanceParameters
from bowden.model.compensation import CompensationModel
from bowden.model.geometry import CuffGeometry
from bowden.model.model_file import load_model


class Controller:
    """The paper's controller for one wearer, support level, suit model and set of limits.

    Build it with :func:`build_controller`. The parameters it was built from are kept as read-only
    attributes (``model``, ``subject``, ``arm``, ``geometry``, ``assistance``, ``limits``); the
    cycle-to-cycle state (the last command, for the rate limit; the dynamic compensation's estimator
    and reversal state) lives in the step.

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
        "_access", "arm", "assistance", "compensation", "geometry", "limits", "model", "step", "subject",
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
        if compensation == "dynamic" and model.dynamic is None:
            raise ParameterError(
                "compensation 'dynamic' needs a model with its dynamic part (model.json version 2, written "
                "by bowden identify); this model holds the paper's lines only"
            )
        if compensation not in ("paper", "dynamic"):
            raise ParameterError(f"compensation must be 'paper' or 'dynamic', got {compensation!r}")
        self._access = compile_step(model, compensation, arm, geometry, assistance, limits)
        self.step: StepFunction = self._access.step

    def reset(self) -> None:
        """Forget the last command: the next torque ramps up from zero again."""
        self._access.reset()

    @property
    def last_torque_nm(self) -> float:
        """The torque of the last command (0 after a fault or reset)."""
        return self._access.torque_nm()


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
    speed: str | None = None,
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
        the model holds one and recommends it at this support and ``speed``,
        :meth:`DynamicCompensation.recommended_for`).
    speed
        The trial's speed ("V1"…), for the model's per-cell recommendation; None when unknown: then
        the dynamic compensation only if the bench showed it winning at every speed of this support.

    Raises
    ------
    bowden.errors.ParameterError, bowden.errors.ModelFileError
        For invalid parameters or an unreadable model file.
    """
    loaded = model if isinstance(model, CompensationModel) else load_model(model)
    if compensation is None:
        chosen = loaded.dynamic is not None and loaded.dynamic.recommended_for(support, speed)
        compensation = "dynamic" if chosen else "paper"
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
