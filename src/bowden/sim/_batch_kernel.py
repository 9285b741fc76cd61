"""Compiled loop of one study trial: IMU → the controller → motor → plant ← participant.

The controller arithmetic of :meth:`bowden.control.Controller.step` — the paper's compensation and
the dynamic one (:mod:`bowden.control.step`) — is restated here on a parameter vector so that
a whole trial runs as one compiled loop; ``tests/sim/test_batch.py`` and
``tests/control/test_dynamic_step.py`` check that both agree to 1e-12 on the same inputs. Keep them in
step: any change there is a change here.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from bowden.control import Controller
from bowden.control.folding import fold
from bowden.model.elevation_estimator import estimator_gains
from bowden.sim import _kernels as k
from bowden.sim._kernels import drop_stale_dependent_cache, jit

# --- controller parameter vector -----------------------------------------------------------------
C_PRETENSION = 0  # NaN: support law
C_SUPPORT_MOMENT = 1  # support·g·Σ m·d, Nm
C_FLOOR = 2
C_MAX_TENSION = 3
C_LOW_INTERCEPT = 4
C_LOW_SLOPE = 5
C_D_INTERCEPT = 6
C_D_SLOPE = 7
C_BLEND_MID = 8
C_BLEND_STEEP = 9
C_MIN_TORQUE = 10
C_MAX_TORQUE = 11
C_MAX_RATE = 12
C_NOMINAL_DT = 13
C_ELEV_MIN = 14
C_ELEV_MAX = 15
C_MAX_VEL = 16
C_MAX_MOTOR_VEL = 17
C_GEOM_A = 18
C_GEOM_B = 19
C_GEOM_PSI = 20
# Dynamic compensation (C_MODE 1; the lines above are then the dynamic model's).
C_MODE = 21
C_VISCOUS_PER_ARM = 22
C_INERTIA_PER_ARM = 23
C_MAX_DYNAMIC = 24
C_HYSTERESIS = 25
C_RELAX = 26
C_LATENCY = 27
C_PERIOD = 28
C_GAIN = 29  # 8 entries: the estimator's gain row by row
N_CONTROLLER = 37

MODE_PAPER = 0.0
MODE_DYNAMIC = 1.0

# Controller state: last torque and its time; the dynamic step's estimator and reversal state.
CS_TORQUE = 0
CS_TIME = 1
CS_TH = 2
CS_W = 3
CS_ACC = 4
CS_BIAS = 5
CS_STARTED = 6
CS_SIGMA = 7
CS_TARGET = 8
N_CONTROLLER_STATE = 9

# Fault and limit bits (bowden.control.faults; recording contract, never renumbered).
FAULT_NONFINITE = 1
FAULT_ELEVATION = 2
FAULT_VELOCITY = 4
FAULT_OVERSPEED = 8
LIMIT_TENSION = 1
LIMIT_TORQUE = 2
LIMIT_RATE = 4


def controller_vector(controller: Controller) -> NDArray[np.float64]:
    """Pack a built controller's constants the way its step closure folds them."""
    c = np.zeros(N_CONTROLLER)
    model, geometry, limits = controller.model, controller.geometry, controller.limits
    folded = fold(controller.arm, geometry, controller.assistance, limits)  # as the step closures do
    c[C_PRETENSION] = folded.pretension
    c[C_SUPPORT_MOMENT] = folded.support_moment
    c[C_FLOOR] = folded.floor
    c[C_MAX_TENSION] = folded.max_tension
    lines = model if controller.compensation == "paper" or model.dynamic is None else model.dynamic
    c[C_LOW_INTERCEPT] = lines.lowering.intercept_nm
    c[C_LOW_SLOPE] = lines.lowering.slope_m
    c[C_D_INTERCEPT] = lines.raising.intercept_nm - lines.lowering.intercept_nm
    c[C_D_SLOPE] = lines.raising.slope_m - lines.lowering.slope_m
    c[C_BLEND_MID] = model.blend_midpoint_rad_s
    c[C_BLEND_STEEP] = model.blend_steepness_s_rad
    c[C_MIN_TORQUE] = folded.min_torque
    c[C_MAX_TORQUE] = folded.max_torque
    c[C_MAX_RATE] = folded.max_rate
    c[C_NOMINAL_DT] = folded.nominal_dt
    c[C_ELEV_MIN] = folded.elev_min
    c[C_ELEV_MAX] = folded.elev_max
    c[C_MAX_VEL] = folded.max_vel
    c[C_MAX_MOTOR_VEL] = folded.max_motor_vel
    c[C_GEOM_A] = geometry.exit_distance_m
    c[C_GEOM_B] = geometry.anchor_distance_m
    c[C_GEOM_PSI] = geometry.rest_angle_rad
    c[C_MODE] = MODE_PAPER
    dynamic = model.dynamic
    if controller.compensation == "dynamic" and dynamic is not None:
        gains = estimator_gains(limits.nominal_period_s, dynamic.imu_latency_s)
        c[C_MODE] = MODE_DYNAMIC
        c[C_VISCOUS_PER_ARM] = dynamic.viscous_nm_s_rad / model.pulley_radius_m
        c[C_INERTIA_PER_ARM] = dynamic.inertia_kg_m2 / model.pulley_radius_m
        c[C_MAX_DYNAMIC] = dynamic.max_dynamic_nm
        c[C_HYSTERESIS] = dynamic.reversal_hysteresis_rad_s
        c[C_RELAX] = 1.0 - math.exp(-limits.nominal_period_s / dynamic.reversal_time_s)
        c[C_LATENCY] = gains.latency_s
        c[C_PERIOD] = limits.nominal_period_s
        c[C_GAIN : C_GAIN + 8] = [value for row in gains.gain for value in row]
    return c


def controller_state() -> NDArray[np.float64]:
    """A fresh controller state (no last command, estimator not started)."""
    cs = np.zeros(N_CONTROLLER_STATE)
    cs[CS_TIME] = math.nan
    return cs


@jit
def controller_step(
    c: NDArray[np.float64],
    cs: NDArray[np.float64],
    time_s: float,
    elevation: float,
    velocity: float,
    motor_velocity: float,
    motor_torque: float,
    out: NDArray[np.float64],
) -> None:
    """One cycle of the paper's controller; ``out`` = (torque, tension, moment arm, faults, limits)."""
    motor_velocity_bad = motor_velocity == motor_velocity and not (
        -c[C_MAX_MOTOR_VEL] <= motor_velocity <= c[C_MAX_MOTOR_VEL]
    )
    motor_torque_bad = motor_torque - motor_torque != 0.0 and motor_torque == motor_torque
    if (
        not (
            c[C_ELEV_MIN] <= elevation <= c[C_ELEV_MAX]
            and -c[C_MAX_VEL] <= velocity <= c[C_MAX_VEL]
            and time_s - time_s == 0.0
        )
        or motor_velocity_bad
        or motor_torque_bad
    ):
        cs[CS_TORQUE] = 0.0
        cs[CS_TIME] = math.nan
        cs[CS_STARTED] = 0.0
        cs[CS_SIGMA] = 0.0
        cs[CS_TARGET] = 0.0
        faults = 0
        finite = math.isfinite(time_s) and math.isfinite(elevation) and math.isfinite(velocity)
        if not finite or math.isinf(motor_velocity) or math.isinf(motor_torque):
            faults |= FAULT_NONFINITE
        if math.isfinite(elevation) and not (c[C_ELEV_MIN] <= elevation <= c[C_ELEV_MAX]):
            faults |= FAULT_ELEVATION
        if math.isfinite(velocity) and abs(velocity) > c[C_MAX_VEL]:
            faults |= FAULT_VELOCITY
        if math.isfinite(motor_velocity) and abs(motor_velocity) > c[C_MAX_MOTOR_VEL]:
            faults |= FAULT_OVERSPEED
        out[0] = 0.0
        out[1] = math.nan
        out[2] = math.nan
        out[3] = faults
        out[4] = 0.0
        return
    dynamic = c[C_MODE] == MODE_DYNAMIC
    velocity_used = velocity
    if dynamic:
        elevation, velocity_used = _estimate(c, cs, elevation, velocity)
    a = c[C_GEOM_A]
    b = c[C_GEOM_B]
    alpha = c[C_GEOM_PSI] - elevation
    sin_alpha = math.sin(alpha)
    cos_alpha = math.cos(alpha)
    d = (a * a + b * b) - (2.0 * a * b) * cos_alpha
    root = math.sqrt(d)
    moment_arm = a * b * sin_alpha / root
    limited = 0
    tension = c[C_PRETENSION]
    if tension != tension:
        tension = c[C_FLOOR]
        if moment_arm > 0.0:
            supported = c[C_SUPPORT_MOMENT] * math.sin(elevation) / moment_arm
            if supported > tension:
                tension = supported
    if tension > c[C_MAX_TENSION]:
        tension = c[C_MAX_TENSION]
        limited = LIMIT_TENSION
    if dynamic:
        if velocity_used > c[C_HYSTERESIS]:
            cs[CS_TARGET] = 1.0
        elif velocity_used < -c[C_HYSTERESIS]:
            cs[CS_TARGET] = -1.0
        cs[CS_SIGMA] += (cs[CS_TARGET] - cs[CS_SIGMA]) * c[C_RELAX]
        slope = -(a * b) * (cos_alpha * d - (a * b) * sin_alpha * sin_alpha) / (d * root)
        extra = c[C_VISCOUS_PER_ARM] * moment_arm * velocity_used + c[C_INERTIA_PER_ARM] * (
            moment_arm * cs[CS_ACC] + slope * velocity_used * velocity_used
        )
        if extra > c[C_MAX_DYNAMIC]:
            extra = c[C_MAX_DYNAMIC]
        elif extra < -c[C_MAX_DYNAMIC]:
            extra = -c[C_MAX_DYNAMIC]
        torque = (
            c[C_LOW_INTERCEPT] + c[C_LOW_SLOPE] * tension
            + (c[C_D_INTERCEPT] + c[C_D_SLOPE] * tension) * 0.5 * (cs[CS_SIGMA] + 1.0)
            + extra
        )
    else:
        xb = c[C_BLEND_STEEP] * (velocity - c[C_BLEND_MID])
        if xb >= 0.0:
            weight = 1.0 / (1.0 + math.exp(-xb))
        else:
            e = math.exp(xb)
            weight = e / (1.0 + e)
        torque = c[C_LOW_INTERCEPT] + c[C_LOW_SLOPE] * tension
        torque += (c[C_D_INTERCEPT] + c[C_D_SLOPE] * tension) * weight
    if torque > c[C_MAX_TORQUE]:
        torque = c[C_MAX_TORQUE]
        limited |= LIMIT_TORQUE
    elif torque < c[C_MIN_TORQUE]:
        torque = c[C_MIN_TORQUE]
        limited |= LIMIT_TORQUE
    dt = time_s - cs[CS_TIME]
    if not (0.0 < dt < 0.1):
        dt = c[C_NOMINAL_DT]
    step_max = c[C_MAX_RATE] * dt
    if torque > cs[CS_TORQUE] + step_max:
        torque = cs[CS_TORQUE] + step_max
        limited |= LIMIT_RATE
    elif torque < cs[CS_TORQUE] - step_max:
        torque = cs[CS_TORQUE] - step_max
        limited |= LIMIT_RATE
    cs[CS_TORQUE] = torque
    cs[CS_TIME] = time_s
    out[0] = torque
    out[1] = tension
    out[2] = moment_arm
    out[3] = 0.0
    out[4] = limited


@jit
def _estimate(
    c: NDArray[np.float64], cs: NDArray[np.float64], elevation: float, gyro: float
) -> tuple[float, float]:
    """The dynamic step's estimator: update, then predict across the latency (elevation clamped)."""
    period = c[C_PERIOD]
    if cs[CS_STARTED] != 0.0:
        cs[CS_TH] += cs[CS_W] * period + 0.5 * period * period * cs[CS_ACC]
        cs[CS_W] += cs[CS_ACC] * period
        e0 = elevation - cs[CS_TH]
        e1 = gyro - cs[CS_W] - cs[CS_BIAS]
        g = C_GAIN
        cs[CS_TH] += c[g] * e0 + c[g + 1] * e1
        cs[CS_W] += c[g + 2] * e0 + c[g + 3] * e1
        cs[CS_ACC] += c[g + 4] * e0 + c[g + 5] * e1
        cs[CS_BIAS] += c[g + 6] * e0 + c[g + 7] * e1
    else:
        cs[CS_TH] = elevation
        cs[CS_W] = gyro
        cs[CS_ACC] = 0.0
        cs[CS_BIAS] = 0.0
        cs[CS_STARTED] = 1.0
    latency = c[C_LATENCY]
    predicted_velocity = cs[CS_W] + cs[CS_ACC] * latency
    predicted = cs[CS_TH] + (cs[CS_W] + 0.5 * cs[CS_ACC] * latency) * latency
    if predicted > c[C_ELEV_MAX]:
        predicted = c[C_ELEV_MAX]
    elif predicted < c[C_ELEV_MIN]:
        predicted = c[C_ELEV_MIN]
    return predicted, predicted_velocity


# --- recorded signals of a trial, one row per control cycle ----------------------------------------
O_REFERENCE = 0
O_ELEVATION = 1
O_VELOCITY = 2
O_DESIRED_TENSION = 3
O_MOMENT_ARM = 4
O_COMMANDED_TORQUE = 5
O_MOTOR_TORQUE = 6
O_MOTOR_VELOCITY = 7
O_TENSION = 8
O_FAULT = 9
O_LIMITS = 10
O_TRUE_TENSION = 11
O_TRUE_ELEVATION = 12
O_TRUE_VELOCITY = 13
O_SHOULDER_TORQUE = 14
O_STUCK = 15
O_CORRECTION_TORQUE = 16
O_COCONTRACTION = 17
N_OUT = 18

# Sensor settings vector of a trial.
S_IMU_EL_NOISE = 0
S_IMU_EL_BIAS = 1
S_IMU_VEL_NOISE = 2
S_IMU_VEL_BIAS = 3
S_LOAD_NOISE = 4
S_LOAD_OFFSET = 5
S_IMU_DELAY_CYCLES = 6  # IMU latency in whole control cycles
N_SENSOR = 7


@jit
def float32_reading(value: float) -> float:
    """A value sent as float32 (the NGIMU's OSC floats), read back as float64."""
    return float(np.float32(value))


@jit
def run_trial(
    x: NDArray[np.float64],
    p: NDArray[np.float64],
    h: NDArray[np.float64],
    c: NDArray[np.float64],
    sensors: NDArray[np.float64],
    wears_suit: bool,
    control_dt: float,
    substeps: int,
    draws_control: NDArray[np.float64],
    draws_human: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:
    """Run one trial of ``out.shape[0]`` control cycles.

    Each cycle at ``t = i·control_dt``: the IMU and the load cell sample the true state (with noise;
    the IMU's readings rounded to float32 as the NGIMU sends them), the controller computes a torque
    from the IMU, the motor reply of that moment is recorded, then the plant runs ``substeps`` steps
    with that command while the participant moves. Without the suit the arm moves freely (no cable,
    controller not run, suit signals NaN). ``draws_control`` holds three unit normal draws per cycle
    (IMU elevation, IMU velocity, load cell), ``draws_human`` one per step.
    The motor's reply and the load cell are recorded at full precision here and quantised to their
    codes afterwards (:mod:`bowden.sim.sensor_readings`; the controller only checks them for faults).
    """
    dt = control_dt / substeps
    lag = 1.0 - math.exp(-dt / p[k.P_CURRENT_TAU])
    cs = np.zeros(N_CONTROLLER_STATE)
    cs[CS_TIME] = math.nan
    command = np.zeros(5)
    delay = int(sensors[S_IMU_DELAY_CYCLES])
    history_th = np.full(delay + 1, x[k.X_ARM_TH])
    history_thd = np.full(delay + 1, x[k.X_ARM_THD])
    shoulder = 0.0
    nan = math.nan
    for i in range(out.shape[0]):
        t = i * control_dt
        ref, _, _ = k.reference_state(h, t)
        th = x[k.X_ARM_TH]
        thd = x[k.X_ARM_THD]
        slot = i % (delay + 1)  # ring buffer: the oldest entry is the sample the IMU delivers now
        history_th[slot] = th
        history_thd[slot] = thd
        late = (i + 1) % (delay + 1)
        elevation = history_th[late] + sensors[S_IMU_EL_BIAS]
        elevation = float32_reading(elevation + sensors[S_IMU_EL_NOISE] * draws_control[i, 0])
        velocity = history_thd[late] + sensors[S_IMU_VEL_BIAS]
        velocity = float32_reading(velocity + sensors[S_IMU_VEL_NOISE] * draws_control[i, 1])
        row = out[i]
        row[O_REFERENCE] = ref
        row[O_ELEVATION] = elevation
        row[O_VELOCITY] = velocity
        row[O_TRUE_ELEVATION] = th
        row[O_TRUE_VELOCITY] = thd
        row[O_SHOULDER_TORQUE] = shoulder
        row[O_CORRECTION_TORQUE] = x[k.X_CORRECTION]
        row[O_COCONTRACTION] = x[k.X_COCONTRACTION]
        if wears_suit:
            motor_velocity = x[k.X_SPOOL_W]
            motor_torque = x[k.X_MOTOR_TAU] / p[k.P_KT_RATIO]
            controller_step(c, cs, t, elevation, velocity, motor_velocity, motor_torque, command)
            row[O_DESIRED_TENSION] = command[1]
            row[O_MOMENT_ARM] = command[2]
            row[O_COMMANDED_TORQUE] = command[0]
            row[O_MOTOR_TORQUE] = motor_torque
            row[O_MOTOR_VELOCITY] = motor_velocity
            row[O_TENSION] = (
                x[k.X_T_OUT] + sensors[S_LOAD_OFFSET] + sensors[S_LOAD_NOISE] * draws_control[i, 2]
            )
            row[O_FAULT] = command[3]
            row[O_LIMITS] = command[4]
            row[O_TRUE_TENSION] = x[k.X_T_OUT]
            row[O_STUCK] = x[k.X_STUCK]
        else:
            row[O_DESIRED_TENSION] = nan
            row[O_MOMENT_ARM] = nan
            row[O_COMMANDED_TORQUE] = nan
            row[O_MOTOR_TORQUE] = nan
            row[O_MOTOR_VELOCITY] = nan
            row[O_TENSION] = nan
            row[O_FAULT] = 0.0
            row[O_LIMITS] = 0.0
            row[O_TRUE_TENSION] = nan
            row[O_STUCK] = nan
        torque_cmd = command[0]
        base = i * substeps
        for j in range(substeps):
            shoulder = k.human_torque(x, p, h, dt, draws_human[base + j, 0], draws_human[base + j, 1])
            if wears_suit:
                k.plant_step(x, p, dt, torque_cmd, lag, k.ARM_TORQUE, shoulder, 0.0)
            else:
                x[k.X_T_OUT] = 0.0
                k.arm_step(x, p, dt, shoulder)
                x[k.X_TIME] += dt


# run_trial compiles the plant of _kernels.py into itself; numba would reuse a cache made with older
# kernels (it only watches this file), so drop that cache whenever either file changed.
drop_stale_dependent_cache(run_trial, __file__, k.__file__)
