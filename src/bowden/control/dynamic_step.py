"""The controller's step with the dynamic compensation (:mod:`bowden.model.dynamic`).

Same contract, inputs, limits and fault behaviour as the paper's step in
:mod:`bowden.control.controller`; what differs is where elevation and velocity come from (the
estimator of :mod:`bowden.model.elevation_estimator`, inlined) and how the torque is made from the
desired tension (reversal state, drag and inertia). Constants are folded into a closure for the same
reason as there: closure variables are the cheapest loads CPython has.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from bowden.control.command import Command, StepFunction, fault_command
from bowden.control.faults import Limit
from bowden.control.folding import fold
from bowden.control.limits import ControllerLimits
from bowden.model.anthropometry import ArmModel
from bowden.model.assistance import AssistanceParameters
from bowden.model.dynamic import DynamicCompensation
from bowden.model.elevation_estimator import estimator_gains
from bowden.model.geometry import CuffGeometry

_NAN = math.nan
_sin, _cos, _sqrt = math.sin, math.cos, math.sqrt
_TENSION = int(Limit.TENSION)
_TORQUE = int(Limit.TORQUE)
_RATE = int(Limit.TORQUE_RATE)


def compile_dynamic_step(
    dynamic: DynamicCompensation,
    pulley_radius_m: float,
    arm: ArmModel,
    geometry: CuffGeometry,
    assistance: AssistanceParameters,
    limits: ControllerLimits,
) -> tuple[StepFunction, Callable[[], None], Callable[[], float]]:
    """Fold every constant into a step closure; return it with ``reset`` and ``last torque`` accessors."""
    (
        ab, aabb, two_ab, psi, pretension, support_moment, floor, max_tension,
        min_torque, max_torque, max_rate, nominal_dt, elev_min, elev_max, max_vel, max_motor_vel,
    ) = fold(arm, geometry, assistance, limits)
    min_vel, min_motor_vel = -max_vel, -max_motor_vel
    low_intercept, low_slope = dynamic.lowering.intercept_nm, dynamic.lowering.slope_m
    d_intercept = dynamic.raising.intercept_nm - low_intercept
    d_slope = dynamic.raising.slope_m - low_slope
    viscous_per_arm = dynamic.viscous_nm_s_rad / pulley_radius_m  # × r·θ̇ = drag at the implied spool speed
    inertia_per_arm = dynamic.inertia_kg_m2 / pulley_radius_m
    max_dynamic = dynamic.max_dynamic_nm
    hysteresis = dynamic.reversal_hysteresis_rad_s
    period = limits.nominal_period_s
    relax = 1.0 - math.exp(-period / dynamic.reversal_time_s)
    gains = estimator_gains(period, dynamic.imu_latency_s)
    (k00, k01), (k10, k11), (k20, k21), (k30, k31) = gains.gain
    latency, half_dt2 = gains.latency_s, 0.5 * period * period
    # Estimator (θ, θ̇, θ̈, gyro bias), reversal state and target, last command.
    th = w = acc = bias = 0.0
    started = False
    sigma = target = 0.0
    last_torque = 0.0
    last_time = _NAN

    def step(
        time_s: float,
        elevation_rad: float,
        elevation_velocity_rad_s: float,
        motor_velocity_rad_s: float = _NAN,
        motor_torque_nm: float = _NAN,
    ) -> Command:
        nonlocal th, w, acc, bias, started, sigma, target, last_torque, last_time
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
        velocity = w + acc * latency
        elevation = th + (w + 0.5 * acc * latency) * latency
        if elevation > elev_max:  # a prediction past the range must not leave the cuff geometry
            elevation = elev_max
        elif elevation < elev_min:
            elevation = elev_min

        alpha = psi - elevation
        sin_alpha, cos_alpha = _sin(alpha), _cos(alpha)
        d = aabb - two_ab * cos_alpha
        root = _sqrt(d)
        moment_arm = ab * sin_alpha / root
        limited = 0
        tension = pretension
        if tension != tension:  # support law
            tension = floor
            if moment_arm > 0.0:
                supported = support_moment * _sin(elevation) / moment_arm
                if supported > tension:
                    tension = supported
        if tension > max_tension:
            tension = max_tension
            limited = _TENSION

        # Reversal state: a new direction only beyond the hysteresis, approached smoothly.
        if velocity > hysteresis:
            target = 1.0
        elif velocity < -hysteresis:
            target = -1.0
        sigma += (target - sigma) * relax
        # Spool motion implied by the arm (cable taut): ω_s = r·θ̇/R, α_s = (r·θ̈ + r'·θ̇²)/R.
        moment_arm_slope = -ab * (cos_alpha * d - ab * sin_alpha * sin_alpha) / (d * root)
        dynamic_nm = viscous_per_arm * moment_arm * velocity + inertia_per_arm * (
            moment_arm * acc + moment_arm_slope * velocity * velocity
        )
        if dynamic_nm > max_dynamic:
            dynamic_nm = max_dynamic
        elif dynamic_nm < -max_dynamic:
            dynamic_nm = -max_dynamic
        torque = (
            low_intercept + low_slope * tension + (d_intercept + d_slope * tension) * 0.5 * (sigma + 1.0)
            + dynamic_nm
        )

        if torque > max_torque:
            torque = max_torque
            limited |= _TORQUE
        elif torque < min_torque:
            torque = min_torque
            limited |= _TORQUE
        dt = time_s - last_time
        if not 0.0 < dt < 0.1:
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
        nonlocal last_torque, last_time, started, sigma, target
        last_torque, last_time, started, sigma, target = 0.0, _NAN, False, 0.0, 0.0

    def torque_nm() -> float:
        return last_torque

    return step, reset, torque_nm
