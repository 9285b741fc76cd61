"""The controller's step: the one definition of its arithmetic, for the paper's and the dynamic compensation.

Each cycle (paper, "Control architecture"; the dynamic parts: :mod:`bowden.model.dynamic`):

1. with the dynamic compensation, the elevation, velocity and acceleration are the estimator's,
   updated with this sample and predicted across the IMU's latency
   (:mod:`bowden.model.elevation_estimator`); otherwise the IMU's own;
2. desired tension T = max(T_floor, support·τ_g(θ)/r(θ)) or the constant pretension, clamped to the
   maximum tension (:mod:`bowden.model.assistance`);
3. motor torque from the raising and lowering lines: blended by the paper's sigmoid of the velocity
   (:mod:`bowden.model.compensation`), or by the reversal state plus the drag and inertia of the
   spool motion the arm implies (:mod:`bowden.model.dynamic`);
4. torque clamped to the motor's range (never below zero: a cable cannot push) and rate-limited.

Every constant is folded into the closure's cells (on CPython a closure variable is the cheapest load
there is). It is written once, in :func:`step_closure`, for both compensations: a short step that
calls one part per item above, each a plain function of this module. :func:`compile_step` gives the
controller that definition with its parts spliced in (:mod:`bowden.control.splice`) and only its
compensation's branches, compiled from the same lines at import: plain float arithmetic with no
calls but ``math``'s. The batch simulator runs the same arithmetic compiled:
``bowden.sim._controller_kernel`` is generated from the spliced step by
:mod:`bowden.sim.controller_codegen` (a test fails when it is out of date) and reads the constants
from the cells of :func:`step_closure`. Change the arithmetic here, then regenerate.
"""

from __future__ import annotations

import ast
import copy
import inspect
import math
import sys
from collections.abc import Callable
from typing import Literal, NamedTuple

from bowden.control.command import Command, StepFunction, fault_command
from bowden.control.faults import Limit
from bowden.control.folding import fold
from bowden.control.limits import ControllerLimits
from bowden.control.splice import module_functions, splice
from bowden.model.anthropometry import ArmModel
from bowden.model.assistance import AssistanceParameters
from bowden.model.compensation import CompensationModel
from bowden.model.elevation_estimator import estimator_gains
from bowden.model.geometry import CuffGeometry

_NAN = math.nan
# Bound once: a module global is one lookup on the hot path, math.sin two.
_sin, _cos, _sqrt, _exp = math.sin, math.cos, math.sqrt, math.exp
_TENSION = int(Limit.TENSION)
_TORQUE = int(Limit.TORQUE)
_RATE = int(Limit.TORQUE_RATE)


class StepAccess(NamedTuple):
    """A compiled step with access to its state from outside the hot path."""

    step: StepFunction
    reset: Callable[[], None]
    torque_nm: Callable[[], float]


class _Compensation(NamedTuple):
    """The compensation's constants as the step uses them (the dynamic ones zero for the paper's)."""

    dynamic: bool
    low_intercept: float
    low_slope: float
    d_intercept: float  # raising minus lowering
    d_slope: float
    blend_mid: float
    blend_steep: float
    viscous_per_arm: float  # × r·θ̇ = drag at the spool speed the arm implies
    inertia_per_arm: float
    max_dynamic: float
    hysteresis: float
    relax: float  # the reversal state's approach per period
    latency: float
    period: float
    gain: tuple[float, float, float, float, float, float, float, float]  # the estimator's, row by row


def _compensation(model: CompensationModel, mode: Literal["paper", "dynamic"],
                  limits: ControllerLimits) -> _Compensation:
    dynamic = model.dynamic if mode == "dynamic" else None
    lines = model if dynamic is None else dynamic
    low, high = lines.lowering, lines.raising
    common = (low.intercept_nm, low.slope_m, high.intercept_nm - low.intercept_nm, high.slope_m - low.slope_m,
              model.blend_midpoint_rad_s, model.blend_steepness_s_rad)
    period = limits.nominal_period_s
    if dynamic is None:
        return _Compensation(False, *common, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, period, (0.0,) * 8)
    gains = estimator_gains(period, dynamic.imu_latency_s)
    (k00, k01), (k10, k11), (k20, k21), (k30, k31) = gains.gain
    return _Compensation(
        True, *common, dynamic.viscous_nm_s_rad / model.pulley_radius_m,
        dynamic.inertia_kg_m2 / model.pulley_radius_m, dynamic.max_dynamic_nm,
        dynamic.reversal_hysteresis_rad_s, 1.0 - math.exp(-period / dynamic.reversal_time_s),
        gains.latency_s, period, (k00, k01, k10, k11, k20, k21, k30, k31),
    )


def compile_step(model: CompensationModel, mode: Literal["paper", "dynamic"], arm: ArmModel,
                 geometry: CuffGeometry, assistance: AssistanceParameters,
                 limits: ControllerLimits) -> StepAccess:
    """The step of ``mode`` with every constant folded in, and accessors of its state."""
    factory = _SPECIALISED[mode == "dynamic" and model.dynamic is not None]
    return factory(model, mode, arm, geometry, assistance, limits)


def step_closure(model: CompensationModel, mode: Literal["paper", "dynamic"], arm: ArmModel,
                 geometry: CuffGeometry, assistance: AssistanceParameters,
                 limits: ControllerLimits) -> StepAccess:
    """Fold every constant into a step closure; return it with accessors of its state.

    The definition of the step, for both compensations (``dynamic`` says which runs). The controller
    runs it specialised (:func:`compile_step`); the batch kernel is generated from it and reads its
    constants from its cells.
    """
    (
        ab, aabb, two_ab, psi, pretension, support_moment, floor, max_tension,
        min_torque, max_torque, max_rate, nominal_dt, elev_min, elev_max, max_vel, max_motor_vel,
    ) = fold(arm, geometry, assistance, limits)
    (
        dynamic, low_intercept, low_slope, d_intercept, d_slope, blend_mid, blend_steep, viscous_per_arm,
        inertia_per_arm, max_dynamic, hysteresis, relax, latency, period, gain,
    ) = _compensation(model, mode, limits)
    k00, k01, k10, k11, k20, k21, k30, k31 = gain
    min_vel, min_motor_vel, half_dt2 = -max_vel, -max_motor_vel, 0.5 * period * period
    # State: the last command; the estimator (θ, θ̇, θ̈, gyro bias) and the reversal state and target.
    last_torque, last_time = 0.0, _NAN
    th = w = acc = bias = sigma = target = 0.0
    started = False

    def step(
        time_s: float,
        elevation_rad: float,
        elevation_velocity_rad_s: float,
        motor_velocity_rad_s: float = _NAN,
        motor_torque_nm: float = _NAN,
    ) -> Command:
        nonlocal last_torque, last_time, th, w, acc, bias, started, sigma, target
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
            # A bad input must not enter the filter: it starts afresh from the next good sample.
            last_torque, last_time, started, sigma, target = 0.0, _NAN, False, 0.0, 0.0
            return fault_command(
                time_s, elevation_rad, elevation_velocity_rad_s, motor_velocity_rad_s, motor_torque_nm,
                elev_min, elev_max, max_vel, max_motor_vel,
            )
        if dynamic:  # the estimator: update, then predict across the latency; the prediction is used
            th, w, acc, bias, started, elevation_rad, elevation_velocity_rad_s = _estimate(
                th, w, acc, bias, started, elevation_rad, elevation_velocity_rad_s, period, half_dt2,
                k00, k01, k10, k11, k20, k21, k30, k31, latency, elev_min, elev_max,
            )
        alpha, sin_alpha, root, moment_arm = _moment_arm(elevation_rad, psi, ab, aabb, two_ab)
        tension, limited = _desired_tension(elevation_rad, moment_arm, pretension, floor, support_moment,
                                            max_tension)
        if dynamic:
            sigma, target, torque = _dynamic_torque(
                elevation_velocity_rad_s, acc, alpha, sin_alpha, root, moment_arm, tension, sigma, target,
                hysteresis, relax, ab, aabb, two_ab, viscous_per_arm, inertia_per_arm, max_dynamic,
                low_intercept, low_slope, d_intercept, d_slope,
            )
        else:
            torque = _paper_torque(elevation_velocity_rad_s, tension, blend_steep, blend_mid, low_intercept,
                                   low_slope, d_intercept, d_slope)
        torque, limited = _limited_torque(torque, limited, time_s, last_time, last_torque, min_torque,
                                          max_torque, nominal_dt, max_rate)
        last_torque, last_time = torque, time_s
        return Command((torque, tension, moment_arm, 0, limited))

    def reset() -> None:
        nonlocal last_torque, last_time, started, sigma, target
        last_torque, last_time, started, sigma, target = 0.0, _NAN, False, 0.0, 0.0

    def torque_nm() -> float:
        return last_torque

    return StepAccess(step, reset, torque_nm)


# The step's parts. The controller runs the step with them spliced in (bowden.control.splice): each
# call becomes the part's statements, so the hot path pays for no call. Their parameters are named
# as the step's variables they read, and they return the names the step assigns.


def _estimate(
    th: float, w: float, acc: float, bias: float, started: bool, elevation_rad: float,
    elevation_velocity_rad_s: float, period: float, half_dt2: float, k00: float, k01: float, k10: float,
    k11: float, k20: float, k21: float, k30: float, k31: float, latency: float, elev_min: float,
    elev_max: float,
) -> tuple[float, float, float, float, bool, float, float]:
    """The estimator (θ, θ̇, θ̈, gyro bias) updated with this sample, and θ, θ̇ predicted across the
    latency (:mod:`bowden.model.elevation_estimator`)."""
    if started:
        th += w * period + half_dt2 * acc
        w += acc * period
        e0 = elevation_rad - th
        e1 = elevation_velocity_rad_s - w - bias
        th += k00 * e0 + k01 * e1
        w += k10 * e0 + k11 * e1
        acc += k20 * e0 + k21 * e1
        bias += k30 * e0 + k31 * e1
    else:
        th, w, acc, bias, started = elevation_rad, elevation_velocity_rad_s, 0.0, 0.0, True
    elevation_velocity_rad_s = w + acc * latency
    elevation_rad = th + (w + 0.5 * acc * latency) * latency
    if elevation_rad > elev_max:  # a prediction past the range must not leave the cuff geometry
        elevation_rad = elev_max
    elif elevation_rad < elev_min:
        elevation_rad = elev_min
    return th, w, acc, bias, started, elevation_rad, elevation_velocity_rad_s


def _moment_arm(elevation_rad: float, psi: float, ab: float, aabb: float,
                two_ab: float) -> tuple[float, float, float, float]:
    """The cable's moment arm r(θ) = ab·sin α / √(a² + b² − 2ab·cos α), α = ψ − θ
    (:mod:`bowden.model.geometry`), with the terms the dynamic compensation reuses."""
    alpha = psi - elevation_rad
    sin_alpha = _sin(alpha)
    root = _sqrt(aabb - two_ab * _cos(alpha))
    moment_arm = ab * sin_alpha / root
    return alpha, sin_alpha, root, moment_arm


def _desired_tension(elevation_rad: float, moment_arm: float, pretension: float, floor: float,
                     support_moment: float, max_tension: float) -> tuple[float, int]:
    """The constant pretension, or the support law max(floor, support·τ_g(θ)/r(θ)); clamped to the
    maximum tension, with the limit's bit."""
    limited = 0
    tension = pretension
    if tension != tension:  # NaN: the support law
        tension = floor
        if moment_arm > 0.0:
            supported = support_moment * _sin(elevation_rad) / moment_arm
            if supported > tension:
                tension = supported
    if tension > max_tension:
        tension = max_tension
        limited = _TENSION
    return tension, limited


def _dynamic_torque(
    elevation_velocity_rad_s: float, acc: float, alpha: float, sin_alpha: float, root: float,
    moment_arm: float, tension: float, sigma: float, target: float, hysteresis: float, relax: float,
    ab: float, aabb: float, two_ab: float, viscous_per_arm: float, inertia_per_arm: float,
    max_dynamic: float, low_intercept: float, low_slope: float, d_intercept: float, d_slope: float,
) -> tuple[float, float, float]:
    """The dynamic compensation's torque (:mod:`bowden.model.dynamic`) and its reversal state.

    A new direction only beyond the hysteresis, approached smoothly; the drag and inertia of the
    spool motion the arm implies (cable taut): ω_s = r·θ̇/R, α_s = (r·θ̈ + r'·θ̇²)/R.
    """
    if elevation_velocity_rad_s > hysteresis:
        target = 1.0
    elif elevation_velocity_rad_s < -hysteresis:
        target = -1.0
    sigma += (target - sigma) * relax
    cos_alpha = _cos(alpha)
    d = aabb - two_ab * cos_alpha
    moment_arm_slope = -ab * (cos_alpha * d - ab * sin_alpha * sin_alpha) / (d * root)
    velocity = elevation_velocity_rad_s
    extra = viscous_per_arm * moment_arm * velocity + inertia_per_arm * (
        moment_arm * acc + moment_arm_slope * velocity * velocity
    )
    if extra > max_dynamic:
        extra = max_dynamic
    elif extra < -max_dynamic:
        extra = -max_dynamic
    weight = 0.5 * (sigma + 1.0)
    torque = low_intercept + low_slope * tension + (d_intercept + d_slope * tension) * weight + extra
    return sigma, target, torque


def _paper_torque(elevation_velocity_rad_s: float, tension: float, blend_steep: float, blend_mid: float,
                  low_intercept: float, low_slope: float, d_intercept: float, d_slope: float) -> float:
    """The paper's torque: the lowering and raising lines blended by a sigmoid of the velocity
    (:mod:`bowden.model.compensation`)."""
    x = blend_steep * (elevation_velocity_rad_s - blend_mid)
    if x >= 0.0:  # two branches so exp never overflows
        weight = 1.0 / (1.0 + _exp(-x))
    else:
        e = _exp(x)
        weight = e / (1.0 + e)
    torque = low_intercept + low_slope * tension + (d_intercept + d_slope * tension) * weight
    return torque


def _limited_torque(torque: float, limited: int, time_s: float, last_time: float, last_torque: float,
                    min_torque: float, max_torque: float, nominal_dt: float,
                    max_rate: float) -> tuple[float, int]:
    """The torque clamped to the motor's range (never below zero: a cable cannot push) and
    rate-limited from the last command, with the limits' bits."""
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
    return torque, limited


def _specialise(dynamic: bool) -> Callable[..., StepAccess]:
    """:func:`step_closure` with its parts spliced in and only its step's branches for ``dynamic``:
    the same source, line for line, without a call per part, the two tests of a closure variable per
    cycle and the other compensation's local variables, which every call's frame would set up (5 % of
    the paper's step in benchmarks/controller.py)."""
    try:
        source = inspect.getsource(sys.modules[__name__])
        filename = inspect.getsourcefile(step_closure) or "<bowden.control.step>"
    except (OSError, TypeError):  # no source to read (a frozen build): the generic step
        return step_closure
    closure, step = spliced_step(ast.parse(source))
    step.body = _taken(step.body, dynamic)
    namespace = dict(globals())
    exec(compile(ast.Module(body=[closure], type_ignores=[]), filename, "exec"), namespace)
    specialised: Callable[..., StepAccess] = namespace["step_closure"]
    return specialised


def spliced_step(module: ast.Module) -> tuple[ast.FunctionDef, ast.FunctionDef]:
    """From this module's parsed source: :func:`step_closure` with its step's parts spliced in, and
    that step (the batch kernel's generator reads it too)."""
    functions = module_functions(module)
    closure = functions["step_closure"]
    index, step = next((i, node) for i, node in enumerate(closure.body)
                       if isinstance(node, ast.FunctionDef) and node.name == "step")
    parts = {name: functions[name] for name in _PARTS}
    closure = copy.copy(closure)
    closure.body = list(closure.body)
    closure.body[index] = step = splice(step, parts, outer=closure)
    return closure, step


def _taken(statements: list[ast.stmt], dynamic: bool) -> list[ast.stmt]:
    """``statements`` with each top-level ``if dynamic: … else: …`` replaced by the branch taken."""
    kept: list[ast.stmt] = []
    for statement in statements:
        test = getattr(statement, "test", None)
        if isinstance(statement, ast.If) and isinstance(test, ast.Name) and test.id == "dynamic":
            kept.extend(statement.body if dynamic else statement.orelse)
        else:
            kept.append(statement)
    return kept


_PARTS = ("_estimate", "_moment_arm", "_desired_tension", "_dynamic_torque", "_paper_torque",
          "_limited_torque")
_SPECIALISED = {False: _specialise(False), True: _specialise(True)}
