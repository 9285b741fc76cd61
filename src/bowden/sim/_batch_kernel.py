"""Compiled loop of one study trial: IMU → the controller → motor → plant ← participant.

The controller is the generated kernel of :mod:`bowden.sim._controller_kernel`: the step closure of
:mod:`bowden.control.step` rewritten for numba (:mod:`bowden.sim.controller_codegen`), on a vector of
the constants a built controller's closure holds and a vector of its state.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from bowden.control import Controller
from bowden.control import command as command_module
from bowden.control.step import step_closure
from bowden.sim import _controller_kernel as ck
from bowden.sim import _kernels as k
from bowden.sim._controller_kernel import controller_step
from bowden.sim._kernels import drop_stale_dependent_cache, jit


def _closure_values(controller: Controller, names: tuple[str, ...]) -> NDArray[np.float64]:
    """The values ``names`` hold in the cells of the controller's step as :func:`step_closure` builds
    it (the kernel's source; the controller runs it specialised), as floats (bools as 0/1)."""
    step = step_closure(controller.model, controller.compensation, controller.arm, controller.geometry,
                        controller.assistance, controller.limits).step
    cells = dict(zip(step.__code__.co_freevars, step.__closure__ or (), strict=True))  # type: ignore[attr-defined]
    return np.array([float(cells[name].cell_contents) for name in names])


def controller_vector(controller: Controller | None) -> NDArray[np.float64]:
    """The constants of a built controller, read from its step closure, in the kernel's order (None:
    zeros, for a trial without the suit, where the controller does not run)."""
    if controller is None:
        return np.zeros(len(ck.CONSTANTS))
    return _closure_values(controller, ck.CONSTANTS)


def controller_state(controller: Controller | None) -> NDArray[np.float64]:
    """The controller's state as the kernel keeps it (a fresh controller's: no command yet)."""
    if controller is None:
        return np.zeros(len(ck.STATE))
    return _closure_values(controller, ck.STATE)


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
    cs: NDArray[np.float64],
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
    (IMU elevation, IMU velocity, load cell), ``draws_human`` one per step. ``c`` and ``cs`` are the
    controller's constants and state (:func:`controller_vector`, :func:`controller_state`; ``cs`` is
    updated in place).
    The motor's reply and the load cell are recorded at full precision here and quantised to their
    codes afterwards (:mod:`bowden.sim.sensor_readings`; the controller only checks them for faults).
    """
    dt = control_dt / substeps
    lag = 1.0 - math.exp(-dt / p[k.P_CURRENT_TAU])
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
            motor_torque = k.reported_torque_nm(x, p)
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


# run_trial compiles the plant of _kernels.py and the controller kernel into itself; numba would reuse
# a cache made with older kernels (it only watches this file), so drop that cache whenever one changed.
drop_stale_dependent_cache(run_trial, __file__, k.__file__, ck.__file__, command_module.__file__)
