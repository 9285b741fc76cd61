"""The controller step compiled for the batch simulator. GENERATED: do not edit.

Written by ``python -m bowden.sim.controller_codegen`` from the step closure of
:mod:`bowden.control.step` (the one definition of the controller's arithmetic); the constants
are the closure's folded variables (``c``), the state its ``nonlocal`` ones (``cs``).
"""

# ruff: noqa
import numpy as np
from numpy.typing import NDArray

from bowden.control.command import fault_bits
from bowden.control.step import _NAN, _RATE, _TENSION, _TORQUE, _cos, _exp, _sin, _sqrt
from bowden.sim._kernels import jit

Vector = NDArray[np.float64]
CONSTANTS = ('aabb', 'ab', 'blend_mid', 'blend_steep', 'd_intercept', 'd_slope', 'dynamic', 'elev_max', 'elev_min', 'floor', 'half_dt2', 'hysteresis', 'inertia_per_arm', 'k00', 'k01', 'k10', 'k11', 'k20', 'k21', 'k30', 'k31', 'latency', 'low_intercept', 'low_slope', 'max_dynamic', 'max_motor_vel', 'max_rate', 'max_tension', 'max_torque', 'max_vel', 'min_motor_vel', 'min_torque', 'min_vel', 'nominal_dt', 'period', 'pretension', 'psi', 'relax', 'support_moment', 'two_ab', 'viscous_per_arm')
STATE = ('last_torque', 'last_time', 'th', 'w', 'acc', 'bias', 'started', 'sigma', 'target')
C_AABB = 0
C_AB = 1
C_BLEND_MID = 2
C_BLEND_STEEP = 3
C_D_INTERCEPT = 4
C_D_SLOPE = 5
C_DYNAMIC = 6
C_ELEV_MAX = 7
C_ELEV_MIN = 8
C_FLOOR = 9
C_HALF_DT2 = 10
C_HYSTERESIS = 11
C_INERTIA_PER_ARM = 12
C_K00 = 13
C_K01 = 14
C_K10 = 15
C_K11 = 16
C_K20 = 17
C_K21 = 18
C_K30 = 19
C_K31 = 20
C_LATENCY = 21
C_LOW_INTERCEPT = 22
C_LOW_SLOPE = 23
C_MAX_DYNAMIC = 24
C_MAX_MOTOR_VEL = 25
C_MAX_RATE = 26
C_MAX_TENSION = 27
C_MAX_TORQUE = 28
C_MAX_VEL = 29
C_MIN_MOTOR_VEL = 30
C_MIN_TORQUE = 31
C_MIN_VEL = 32
C_NOMINAL_DT = 33
C_PERIOD = 34
C_PRETENSION = 35
C_PSI = 36
C_RELAX = 37
C_SUPPORT_MOMENT = 38
C_TWO_AB = 39
C_VISCOUS_PER_ARM = 40
S_LAST_TORQUE = 0
S_LAST_TIME = 1
S_TH = 2
S_W = 3
S_ACC = 4
S_BIAS = 5
S_STARTED = 6
S_SIGMA = 7
S_TARGET = 8

_fault_bits = jit(fault_bits)


@jit
def controller_step(c: Vector, cs: Vector, time_s: float, elevation_rad: float, elevation_velocity_rad_s: float, motor_velocity_rad_s: float, motor_torque_nm: float, out: Vector) -> None:
    if not (c[C_ELEV_MIN] <= elevation_rad <= c[C_ELEV_MAX] and c[C_MIN_VEL] <= elevation_velocity_rad_s <= c[C_MAX_VEL] and (time_s - time_s == 0.0)) or (motor_velocity_rad_s == motor_velocity_rad_s and (not c[C_MIN_MOTOR_VEL] <= motor_velocity_rad_s <= c[C_MAX_MOTOR_VEL])) or (motor_torque_nm == motor_torque_nm and motor_torque_nm - motor_torque_nm != 0.0):
        cs[S_LAST_TORQUE] = 0.0
        cs[S_LAST_TIME] = _NAN
        cs[S_STARTED] = 0.0
        cs[S_SIGMA] = 0.0
        cs[S_TARGET] = 0.0
        out[0] = 0.0
        out[1] = _NAN
        out[2] = _NAN
        out[3] = _fault_bits(time_s, elevation_rad, elevation_velocity_rad_s, motor_velocity_rad_s, motor_torque_nm, c[C_ELEV_MIN], c[C_ELEV_MAX], c[C_MAX_VEL], c[C_MAX_MOTOR_VEL])
        out[4] = 0.0
        return
    if c[C_DYNAMIC]:
        if cs[S_STARTED]:
            cs[S_TH] += cs[S_W] * c[C_PERIOD] + c[C_HALF_DT2] * cs[S_ACC]
            cs[S_W] += cs[S_ACC] * c[C_PERIOD]
            e0 = elevation_rad - cs[S_TH]
            e1 = elevation_velocity_rad_s - cs[S_W] - cs[S_BIAS]
            cs[S_TH] += c[C_K00] * e0 + c[C_K01] * e1
            cs[S_W] += c[C_K10] * e0 + c[C_K11] * e1
            cs[S_ACC] += c[C_K20] * e0 + c[C_K21] * e1
            cs[S_BIAS] += c[C_K30] * e0 + c[C_K31] * e1
        else:
            cs[S_TH] = elevation_rad
            cs[S_W] = elevation_velocity_rad_s
            cs[S_ACC] = 0.0
            cs[S_BIAS] = 0.0
            cs[S_STARTED] = 1.0
        elevation_velocity_rad_s = cs[S_W] + cs[S_ACC] * c[C_LATENCY]
        elevation_rad = cs[S_TH] + (cs[S_W] + 0.5 * cs[S_ACC] * c[C_LATENCY]) * c[C_LATENCY]
        if elevation_rad > c[C_ELEV_MAX]:
            elevation_rad = c[C_ELEV_MAX]
        elif elevation_rad < c[C_ELEV_MIN]:
            elevation_rad = c[C_ELEV_MIN]
    alpha = c[C_PSI] - elevation_rad
    sin_alpha = _sin(alpha)
    root = _sqrt(c[C_AABB] - c[C_TWO_AB] * _cos(alpha))
    moment_arm = c[C_AB] * sin_alpha / root
    limited = 0
    tension = c[C_PRETENSION]
    if tension != tension:
        tension = c[C_FLOOR]
        if moment_arm > 0.0:
            supported = c[C_SUPPORT_MOMENT] * _sin(elevation_rad) / moment_arm
            if supported > tension:
                tension = supported
    if tension > c[C_MAX_TENSION]:
        tension = c[C_MAX_TENSION]
        limited = _TENSION
    if c[C_DYNAMIC]:
        if elevation_velocity_rad_s > c[C_HYSTERESIS]:
            cs[S_TARGET] = 1.0
        elif elevation_velocity_rad_s < -c[C_HYSTERESIS]:
            cs[S_TARGET] = -1.0
        cs[S_SIGMA] += (cs[S_TARGET] - cs[S_SIGMA]) * c[C_RELAX]
        cos_alpha = _cos(alpha)
        d = c[C_AABB] - c[C_TWO_AB] * cos_alpha
        moment_arm_slope = -c[C_AB] * (cos_alpha * d - c[C_AB] * sin_alpha * sin_alpha) / (d * root)
        velocity = elevation_velocity_rad_s
        extra = c[C_VISCOUS_PER_ARM] * moment_arm * velocity + c[C_INERTIA_PER_ARM] * (moment_arm * cs[S_ACC] + moment_arm_slope * velocity * velocity)
        if extra > c[C_MAX_DYNAMIC]:
            extra = c[C_MAX_DYNAMIC]
        elif extra < -c[C_MAX_DYNAMIC]:
            extra = -c[C_MAX_DYNAMIC]
        weight = 0.5 * (cs[S_SIGMA] + 1.0)
        torque = c[C_LOW_INTERCEPT] + c[C_LOW_SLOPE] * tension + (c[C_D_INTERCEPT] + c[C_D_SLOPE] * tension) * weight + extra
    else:
        x = c[C_BLEND_STEEP] * (elevation_velocity_rad_s - c[C_BLEND_MID])
        if x >= 0.0:
            weight = 1.0 / (1.0 + _exp(-x))
        else:
            e = _exp(x)
            weight = e / (1.0 + e)
        torque = c[C_LOW_INTERCEPT] + c[C_LOW_SLOPE] * tension + (c[C_D_INTERCEPT] + c[C_D_SLOPE] * tension) * weight
    if torque > c[C_MAX_TORQUE]:
        torque = c[C_MAX_TORQUE]
        limited |= _TORQUE
    elif torque < c[C_MIN_TORQUE]:
        torque = c[C_MIN_TORQUE]
        limited |= _TORQUE
    dt = time_s - cs[S_LAST_TIME]
    if not 0.0 < dt < 0.1:
        dt = c[C_NOMINAL_DT]
    step_max = c[C_MAX_RATE] * dt
    if torque > cs[S_LAST_TORQUE] + step_max:
        torque = cs[S_LAST_TORQUE] + step_max
        limited |= _RATE
    elif torque < cs[S_LAST_TORQUE] - step_max:
        torque = cs[S_LAST_TORQUE] - step_max
        limited |= _RATE
    cs[S_LAST_TORQUE] = torque
    cs[S_LAST_TIME] = time_s
    out[0] = torque
    out[1] = tension
    out[2] = moment_arm
    out[3] = 0
    out[4] = limited
    return
