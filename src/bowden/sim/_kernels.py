"""Compiled physics of the simulated suit: one fixed plant step and loops over many of them.

The plant (docs/simulation.md) is, from the motor to the arm:

* **motor**: current-loop lag (exact exponential), torque-constant error, torque limit, rotor inertia,
  viscous friction and Coulomb friction integrated by time stepping (Moreau 1988: the friction
  impulse is chosen so that the velocity is zero when it can be), so a motor at rest stays exactly
  at rest instead of chattering;
* **cable** from spool to sheath: a spring that only pulls (``T_in = k_c·max(0, x_m − s)``);
* **sheath**: the cable inside it lumped into one massless node at position ``s`` (> 0 towards the
  motor) held by friction proportional to the normal force ``(T_in + T_out)`` (the paper's single-bend
  law, supplement eq. S1–S5). It sticks while ``|T_in − T_out| ≤ k_s·(T_in + T_out)`` and slides with
  the Stribeck coefficient ``k(v)`` otherwise, plus a viscous drag ``c_v·v`` that does not depend on
  the normal force (the lubricant or liner shearing). Because the node is massless, each step solves
  its position exactly (implicit Euler, piecewise linear), which is stable for any step;
* **distal segment** (textile, tissue, cable to the anchor): a damped spring that only pulls;
* **anchor** on the arm through the cuff geometry (docs/design.md, "Cuff geometry"): path length
  ``L(θ) = sqrt(a² + b² − 2ab·cos(ψ − θ))`` whose derivative is minus the moment arm ``r(θ)``;
* **arm**: prescribed kinematics, or a rigid body driven by an external torque (mannequin motor or a
  virtual participant's muscles), gravity, passive damping and soft joint stops.

Everything is plain float arithmetic on small arrays (state, parameters) indexed by the constants
below, so the same step serves the single suit driven by the runtime loop and the batch simulation.
Sources of each number are in :mod:`bowden.sim.parameters`.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar, cast

import numba
import numpy as np
from numpy.typing import NDArray

_F = TypeVar("_F", bound=Callable[..., Any])


def jit(func: _F) -> _F:
    """Compile ``func`` in nopython mode, cached on disk, keeping its Python signature for mypy."""
    return cast(_F, numba.njit(cache=True, nogil=True)(func))


def drop_stale_dependent_cache(dispatcher: Any, module_file: str, *sources: str) -> bool:
    """Drop the on-disk numba cache of ``module_file`` when any of ``sources`` changed since it was made.

    Numba keys a cached function on its own source file only: a function in another module that calls
    kernels of this one (the batch trial loop calls :func:`plant_step`) would otherwise be loaded from
    its cache with the *old* kernels compiled in, silently simulating the previous physics. A digest of
    the module and its sources is kept beside the cache; when it differs, the module's cache entries
    (``<stem>.*.nbi``/``.nbc``) are removed so numba compiles afresh. Returns True when it dropped any.
    Degrades to doing nothing if numba's cache layout is not the expected one.
    """
    cache_path = getattr(getattr(dispatcher, "_cache", None), "_cache_path", None)
    if not isinstance(cache_path, str):
        return False
    digest = hashlib.sha256()
    for source in (module_file, *sources):
        digest.update(Path(source).read_bytes())
    directory = Path(cache_path)
    stem = Path(module_file).stem
    marker = directory / f"{stem}.sources.sha256"
    with contextlib.suppress(OSError):
        if marker.read_text(encoding="ascii") == digest.hexdigest():
            return False
    dropped = False
    for entry in (*directory.glob(f"{stem}.*.nbi"), *directory.glob(f"{stem}.*.nbc")):
        with contextlib.suppress(OSError):
            entry.unlink()
            dropped = True
    with contextlib.suppress(OSError):
        directory.mkdir(parents=True, exist_ok=True)
        marker.write_text(digest.hexdigest(), encoding="ascii")
    return dropped


GRAVITY_M_S2 = 9.81

# --- parameter vector ---------------------------------------------------------------------------
P_SPOOL_R = 0
P_MOTOR_J = 1
P_MOTOR_COULOMB = 2
P_MOTOR_VISCOUS = 3
P_CURRENT_TAU = 4
P_KT_RATIO = 5
P_TORQUE_LIMIT = 6
P_K_KINETIC = 7
P_K_STATIC = 8
P_V_STRIBECK = 9
P_V_STICK = 10
P_K_CABLE = 11
P_K_DISTAL = 12
P_C_DISTAL = 13
P_GEOM_A = 14
P_GEOM_B = 15
P_GEOM_PSI = 16
P_ARM_I = 17
P_ARM_G = 18
P_ARM_DAMPING = 19
P_ARM_MIN = 20
P_ARM_MAX = 21
P_STOP_K = 22
P_STOP_C = 23
P_SHEATH_VISCOUS = 24
# Structural variants of the plant (:mod:`bowden.sim.plant_structure`); each default keeps the nominal
# physics above bit for bit.
P_PRESLIDE_M = 25  # Dahl presliding: node displacement that builds the breakaway friction (0: rigid stick)
P_STRIBECK_EXP = 26  # exponent of the Stribeck curve (2: Gaussian)
P_VISCOUS_LOAD = 27  # sheath drag per newton of normal force, N·s/m/N
P_WRAP_GAIN = 28  # friction coefficient's growth per rad of elevation (wrap around the shoulder)
P_TENSION_GAIN = 29  # friction coefficient's growth per newton of mean tension (capstan, flattening)
P_PLAY_M = 30  # axial play of the sheath's ends, m (backlash, taken up by the friction force)
P_PLAY_COMPLIANCE = 31  # m/N: how fast the friction force takes up the play
P_SHEATH_COMPLIANCE = 32  # m/N: axial compression of the sheath under the motor-side tension
P_KT_TEMPCO = 33  # 1/K: loss of torque constant per kelvin of winding temperature rise
P_HEATING = 34  # K/Nm²: steady temperature rise per squared delivered torque
P_THERMAL_TAU = 35  # s: thermal time constant of the motor (0: no drift)
N_PARAM = 36

# --- state vector -------------------------------------------------------------------------------
X_SPOOL_Q = 0  # spool angle, rad (> 0 reeling in)
X_SPOOL_W = 1  # spool velocity, rad/s
X_MOTOR_TAU = 2  # delivered motor torque, Nm
X_NODE_S = 3  # sheath node position, m (> 0 towards the motor)
X_SLIP_V = 4  # node velocity of the last step, m/s
X_STUCK = 5  # 1.0 while the sheath sticks
X_SLIP_DIR = 6  # direction of the last slip, ±1
X_ARM_TH = 7  # elevation, rad
X_ARM_THD = 8  # elevation velocity, rad/s
X_T_IN = 9  # tension at the sheath entry (motor side), N
X_T_OUT = 10  # tension at the anchor, N
X_E_SHEATH = 11  # energy dissipated by sheath friction, J
X_E_DISTAL = 12  # energy dissipated by the distal damper, J
X_W_SPOOL = 13  # work done by the spool on the cable, J
X_W_ARM = 14  # work done by the cable on the arm, J
X_E_MOTOR = 15  # energy dissipated by motor friction, J
X_TIME = 16  # simulated time, s
X_NOISE = 17  # virtual participant's motor-noise state (unit-variance Ornstein–Uhlenbeck)
X_DISTAL_STRETCH = 18  # stretch of the distal segment, m (slack when ≤ 0)
X_CORRECTION = 19  # virtual participant's corrective torque of the last step (feedback + learned), Nm
X_COCONTRACTION = 20  # virtual participant's co-contraction torque (each side of the joint), Nm
X_LEARNED = 21  # 3 weights (Nm) of the torque the participant has learned to add: sin θ, friction, θ̇
N_LEARNED = 3
X_LAG_NOISE = 24  # virtual participant's lag deviation (unit-variance Ornstein–Uhlenbeck)
X_FRICTION = 25  # friction force on the sheath node of the last step, T_in − T_out, N
X_SHEATH_SHIFT = 26  # how far the sheath's ends have shifted and compressed (play, compliance), m
X_TEMP_RISE = 27  # motor winding temperature above ambient, K
N_STATE = 28

# --- arm drive modes ----------------------------------------------------------------------------
ARM_PRESCRIBED = 0  # arm_a = elevation, arm_b = elevation velocity
ARM_TORQUE = 1  # arm_a = external torque on the arm (Nm, > 0 raises)
ARM_HUMAN = 2  # torque from the virtual participant's controller (human parameter vector)
# The mannequin's joint motor in MIT mode, evaluated at every step as the motor's own loop does: the
# "human" vector holds (elevation, elevation velocity, kp, kd, feedforward torque, torque limit) in the
# arm's sense (a positive torque raises). A torque held between the host's commands lets the arm run
# on while the host stalls (0.3 s without a command: 85° past the target, tests/sim/test_mannequin_joint.py).
ARM_IMPEDANCE = 3
A_ELEVATION, A_VELOCITY, A_KP, A_KD, A_FEEDFORWARD, A_LIMIT = 0, 1, 2, 3, 4, 5

# --- motor command modes ------------------------------------------------------------------------
MOTOR_TORQUE = 0  # cmd[0] = torque
MOTOR_IMPEDANCE = 1  # cmd = (position, velocity, kp, kd, torque_ff), as the AK60-6 MIT mode
MOTOR_OFF = 2  # limp: no torque
MOTOR_TRAJECTORY = 3  # as MOTOR_IMPEDANCE, with the position target advancing at cmd[1] (host ramp)

# --- recorded columns of integrate() ------------------------------------------------------------
R_TH = 0
R_THD = 1
R_T_OUT = 2
R_SPOOL_Q = 3
R_SPOOL_W = 4
R_MOTOR_TAU = 5
R_ARM_TORQUE = 6
R_REPORTED_TAU = 7  # the driver's torque (its current times the torque constant it assumes)
N_RECORD = 8


@jit
def path_length_m(p: NDArray[np.float64], th: float) -> float:
    """Distance from the cable exit above the shoulder to the anchor on the humerus (docs/design.md, "Cuff
    geometry")."""
    a = p[P_GEOM_A]
    b = p[P_GEOM_B]
    return math.sqrt(a * a + b * b - 2.0 * a * b * math.cos(p[P_GEOM_PSI] - th))


@jit
def moment_arm_m(p: NDArray[np.float64], th: float) -> float:
    """Moment arm of the cable about the shoulder, ``r = ab·sin α / L``, α = ψ − θ (docs/design.md, "Cuff
    geometry")."""
    a = p[P_GEOM_A]
    b = p[P_GEOM_B]
    alpha = p[P_GEOM_PSI] - th
    return float(a * b * math.sin(alpha) / math.sqrt(a * a + b * b - 2.0 * a * b * math.cos(alpha)))


@jit
def anchor_pull_m(p: NDArray[np.float64], th: float) -> float:
    """How far the anchor has pulled the cable towards the motor relative to the arm hanging (θ = 0)."""
    return path_length_m(p, 0.0) - path_length_m(p, th)


@jit
def stribeck_coefficient(p: NDArray[np.float64], slip_speed: float) -> float:
    """``k(v) = k_k + (k_s − k_k)·exp(−|v/v_s|^δ)`` (δ = 2, Gaussian, unless a variant sets it)."""
    ratio = slip_speed / p[P_V_STRIBECK]
    exponent = p[P_STRIBECK_EXP]
    shape = ratio * ratio if exponent == 2.0 else abs(ratio) ** exponent
    return float(p[P_K_KINETIC] + (p[P_K_STATIC] - p[P_K_KINETIC]) * math.exp(-shape))


@jit
def distal_tension_at_rest(p: NDArray[np.float64], s: float, ya: float, yda: float) -> float:
    """Distal tension with the node still: only a stretched segment pulls, and it never pushes."""
    stretch = s - ya
    if stretch <= 0.0:
        return 0.0
    return float(max(0.0, p[P_K_DISTAL] * stretch - p[P_C_DISTAL] * yda))


@jit
def sliding_node_position(
    p: NDArray[np.float64], dt: float, s0: float, xm: float, ya: float, yda: float, sigma: float, k: float,
    viscous: float,
) -> float:
    """Node position after one implicit step of sliding in direction ``sigma`` with coefficient ``k``.

    Sliding balances the node: ``T_in − T_out = σ·k·(T_in + T_out) + c_v·v`` (the paper's law plus the
    sheath's viscous drag ``c_v·v``, ``v = (s − s0)/dt``, ``c_v`` = ``viscous``), i.e.
    ``g·T_in − T_out − c_v·v/(1 + σk) = 0`` with ``g = (1 − σk)/(1 + σk)``. ``T_in`` falls, ``T_out``
    and the drag rise with ``s``, so the balance has one root; every term is piecewise linear in ``s``
    (breakpoints where the motor-side cable and the distal segment go slack), and the root is found in
    closed form piece by piece.
    """
    kc = p[P_K_CABLE]
    kd = p[P_K_DISTAL]
    c = p[P_C_DISTAL] / dt
    g = (1.0 - sigma * k) / (1.0 + sigma * k)
    cv = viscous / ((1.0 + sigma * k) * dt)
    # Where the damped distal force turns positive, and where the segment is taut at all.
    s_damped = (kd * ya + c * s0 + p[P_C_DISTAL] * yda) / (kd + c)
    s_taut = max(ya, s_damped)
    if cv == 0.0 and s_taut >= xm:
        # Both segments slack between xm and s_taut: the node moves no further than it has to.
        return float(min(max(s0, xm), s_taut))
    low = min(s_taut, xm)
    high = max(s_taut, xm)
    for piece in range(3):
        left = -math.inf if piece == 0 else (low if piece == 1 else high)
        right = low if piece == 0 else (high if piece == 1 else math.inf)
        # On this piece the balance is affine, a − b·s; which segments pull decides a and b.
        a = cv * s0
        b = cv
        if right <= xm:
            a += g * kc * xm
            b += g * kc
        if left >= s_taut:
            a += (kd + c) * s_damped
            b += kd + c
        if b <= 0.0:
            return float(min(max(s0, left), right))
        root = a / b
        if root < left:
            # The balance jumps through zero at this breakpoint (a segment turning taut with its
            # damper already pulling): the node stops there, the tension taking up the difference.
            return float(left)
        if root <= right:
            return float(root)
    return float(high)


@jit
def friction_scale(p: NDArray[np.float64], th: float, t_in: float, t_out: float) -> float:
    """Factor on the sheath's friction coefficients (1 for the nominal plant): friction growing with the
    wrap around the shoulder (elevation) and with tension (a capstan whose liner flattens under load),
    bounded so the static coefficient stays below 0.9."""
    scale = max(1.0 + p[P_WRAP_GAIN] * th + p[P_TENSION_GAIN] * 0.5 * (t_in + t_out), 0.1)
    if p[P_K_STATIC] > 0.0:
        scale = min(scale, 0.9 / p[P_K_STATIC])
    return float(scale)


@jit
def presliding_node_position(
    p: NDArray[np.float64], dt: float, s0: float, xm: float, ya: float, yda: float, force0: float,
    stiffness: float,
) -> float:
    """Node position while the sheath sticks elastically (Dahl presliding): the node balances
    ``T_in − T_out = F0 + σ·(s − s0)`` with both segments taut (the distal one damped); NaN when a
    segment would go slack there (then the rigid stick applies)."""
    kc = p[P_K_CABLE]
    kd = p[P_K_DISTAL]
    c = p[P_C_DISTAL] / dt
    numerator = kc * xm + kd * ya + c * s0 + p[P_C_DISTAL] * yda - force0 + stiffness * s0
    s = numerator / (kc + kd + c + stiffness)
    if s >= xm or s <= ya or kd * (s - ya) + c * (s - s0) - p[P_C_DISTAL] * yda < 0.0:
        return math.nan
    return float(s)


@jit
def sheath_step(
    x: NDArray[np.float64], p: NDArray[np.float64], dt: float, xm: float, ya: float, yda: float
) -> None:
    """Advance the sheath node one step with stick–slip friction; updates tensions and energies."""
    s0 = x[X_NODE_S]
    kc = p[P_K_CABLE]
    t_in0 = kc * max(0.0, xm - s0)
    t_out0 = distal_tension_at_rest(p, s0, ya, yda)
    scale = friction_scale(p, x[X_ARM_TH], t_in0, t_out0)
    k_static = p[P_K_STATIC] * scale
    viscous = p[P_SHEATH_VISCOUS] + p[P_VISCOUS_LOAD] * (t_in0 + t_out0)
    imbalance = t_in0 - t_out0
    inside_cone = abs(imbalance) <= k_static * (t_in0 + t_out0)

    stuck = x[X_STUCK] > 0.5
    s1 = s0
    g = 1.0
    k_used = 0.0
    presliding = False
    if not stuck:
        sigma = x[X_SLIP_DIR]
        k = stribeck_coefficient(p, abs(x[X_SLIP_V])) * scale
        s_try = sliding_node_position(p, dt, s0, xm, ya, yda, sigma, k, viscous)
        moved = (s_try - s0) * sigma
        slow = abs(s_try - s0) < p[P_V_STICK] * dt
        if moved > 0.0 and not (slow and inside_cone):
            s1 = s_try
            g = (1.0 - sigma * k) / (1.0 + sigma * k)
            k_used = k
        else:
            stuck = True
    if stuck and p[P_PRESLIDE_M] > 0.0:
        # Dahl (1968): the friction force builds with the node's displacement, dF/ds = σ0·(1 − F·d/F_c),
        # σ0 = F_c / presliding length; the sheath breaks away when the force would pass F_c.
        breakaway_n = k_static * (t_in0 + t_out0)
        force0 = x[X_FRICTION]
        direction = 1.0 if imbalance > force0 else -1.0
        hardening = max(0.05, 1.0 - force0 * direction / max(breakaway_n, 1e-9))
        stiffness = breakaway_n / p[P_PRESLIDE_M] * hardening
        s_elastic = presliding_node_position(p, dt, s0, xm, ya, yda, force0, stiffness)
        if not math.isnan(s_elastic):
            force1 = force0 + stiffness * (s_elastic - s0)
            if abs(force1) <= breakaway_n:
                s1 = s_elastic
                presliding = True
            else:
                inside_cone = False
    if stuck and not presliding:
        if inside_cone:
            s1 = s0
        else:
            # Breakaway: start sliding with the static coefficient (zero slip speed on the curve).
            sigma = 1.0 if imbalance > 0.0 else -1.0
            s1 = sliding_node_position(p, dt, s0, xm, ya, yda, sigma, k_static, viscous)
            g = (1.0 - sigma * k_static) / (1.0 + sigma * k_static)
            k_used = k_static
            stuck = (s1 - s0) * sigma <= 0.0
            if stuck:
                s1 = s0
            else:
                x[X_SLIP_DIR] = sigma

    t_in = kc * max(0.0, xm - s1)
    if presliding:
        t_out = max(0.0, p[P_K_DISTAL] * (s1 - ya) + p[P_C_DISTAL] * ((s1 - s0) / dt - yda))
        x[X_STUCK] = 1.0
        x[X_SLIP_V] = 0.0
    elif stuck:
        t_out = t_out0
        x[X_STUCK] = 1.0
        x[X_SLIP_V] = 0.0
    else:
        # While sliding the node is balanced by definition of the friction law (Coulomb part
        # through g, the viscous drag on top).
        slip_v = (s1 - s0) / dt
        t_out = max(0.0, g * t_in - viscous * slip_v / (1.0 + x[X_SLIP_DIR] * k_used))
        x[X_STUCK] = 0.0
        x[X_SLIP_V] = slip_v
    x[X_FRICTION] = t_in - t_out
    x[X_E_SHEATH] += (t_in - t_out) * (s1 - s0)
    stretch = s1 - ya
    x[X_DISTAL_STRETCH] = stretch
    if stretch > 0.0:
        # The damper's share of the tension (it cancels the spring when the segment cannot push).
        damper = t_out - p[P_K_DISTAL] * stretch
        x[X_E_DISTAL] += damper * ((s1 - s0) - yda * dt)
    x[X_NODE_S] = s1
    x[X_T_IN] = t_in
    x[X_T_OUT] = t_out


@jit
def kt_drift(x: NDArray[np.float64], p: NDArray[np.float64]) -> float:
    """Factor on the torque constant from the winding's temperature rise (1 without thermal drift)."""
    return float(1.0 - p[P_KT_TEMPCO] * x[X_TEMP_RISE])


@jit
def reported_torque_nm(x: NDArray[np.float64], p: NDArray[np.float64]) -> float:
    """The driver's torque: its current times the torque constant it assumes (the delivered torque
    divided by the true constant's ratio to it, drift included)."""
    return float(x[X_MOTOR_TAU] / (p[P_KT_RATIO] * kt_drift(x, p)))


SHIFT_TIME_S = 2e-3  # the sheath's ends follow the friction force and tension with this lag (stability)


@jit
def sheath_shift_m(x: NDArray[np.float64], p: NDArray[np.float64], dt: float) -> float:
    """Advance the shift of the sheath's ends: the axial play taken up by the last friction force and
    the sheath's compression under the motor-side tension (0 for the nominal plant). It shortens the
    cable between spool and node as seen by both."""
    if p[P_PLAY_M] > 0.0 or p[P_SHEATH_COMPLIANCE] > 0.0:
        half = 0.5 * p[P_PLAY_M]
        play = min(max(p[P_PLAY_COMPLIANCE] * x[X_FRICTION], -half), half)
        target = play + p[P_SHEATH_COMPLIANCE] * x[X_T_IN]
        x[X_SHEATH_SHIFT] += (target - x[X_SHEATH_SHIFT]) * (1.0 - math.exp(-dt / SHIFT_TIME_S))
    return float(x[X_SHEATH_SHIFT])


@jit
def motor_step(
    x: NDArray[np.float64], p: NDArray[np.float64], dt: float, torque_cmd: float, lag: float
) -> None:
    """Current loop, then spool dynamics against the cable with Coulomb friction by time stepping."""
    limit = p[P_TORQUE_LIMIT]
    drift = kt_drift(x, p)
    if p[P_THERMAL_TAU] > 0.0:
        # The winding warms with the delivered torque squared (copper loss ∝ current²) and cools to
        # ambient; the magnets' flux, and with it the torque constant, falls as it warms.
        rise = x[X_TEMP_RISE]
        x[X_TEMP_RISE] = rise + (p[P_HEATING] * x[X_MOTOR_TAU] ** 2 - rise) * dt / p[P_THERMAL_TAU]
    # The driver limits its current, not the torque it delivers: the command (in the torque constant
    # it assumes, as it reports) saturates at the peak, and the true, warm constant scales what that
    # current delivers. Saturating the delivered torque instead let the reported torque (current)
    # grow without bound as the constant fell: 57.7 Nm from a 9 Nm motor on a warm suit.
    target = min(max(torque_cmd, -limit), limit) * p[P_KT_RATIO] * drift
    x[X_MOTOR_TAU] += (target - x[X_MOTOR_TAU]) * lag
    j = p[P_MOTOR_J]
    radius = p[P_SPOOL_R]
    stretch = radius * x[X_SPOOL_Q] - x[X_NODE_S] - x[X_SHEATH_SHIFT]
    t_in = p[P_K_CABLE] * max(0.0, stretch)
    # Implicit in the cable spring (while taut) and the viscous friction, so a stiff cable on a light
    # rotor cannot make the step unstable: w_new·a = w + dt/J·(τ − R·T_in − f), f the Coulomb force.
    a = 1.0 + dt * p[P_MOTOR_VISCOUS] / j
    if stretch > 0.0:
        a += dt * dt * radius * radius * p[P_K_CABLE] / j
    v = x[X_SPOOL_W] + dt / j * (x[X_MOTOR_TAU] - radius * t_in)
    impulse = dt * p[P_MOTOR_COULOMB] / j
    w_new = 0.0 if abs(v) <= impulse else (v - math.copysign(impulse, v)) / a
    x[X_E_MOTOR] += (p[P_MOTOR_COULOMB] * abs(w_new) + p[P_MOTOR_VISCOUS] * w_new * w_new) * dt
    x[X_SPOOL_W] = w_new
    x[X_SPOOL_Q] += dt * w_new
    x[X_W_SPOOL] += t_in * radius * w_new * dt


@jit
def arm_step(x: NDArray[np.float64], p: NDArray[np.float64], dt: float, external_torque: float) -> None:
    """Semi-implicit Euler for the rigid arm: external + cable − gravity − damping + joint stops."""
    th = x[X_ARM_TH]
    thd = x[X_ARM_THD]
    torque = external_torque + moment_arm_m(p, th) * x[X_T_OUT] - p[P_ARM_G] * math.sin(th)
    damping = p[P_ARM_DAMPING]
    if th < p[P_ARM_MIN]:
        torque += p[P_STOP_K] * (p[P_ARM_MIN] - th)
        damping += p[P_STOP_C]
    elif th > p[P_ARM_MAX]:
        torque += p[P_STOP_K] * (p[P_ARM_MAX] - th)
        damping += p[P_STOP_C]
    inertia = p[P_ARM_I]
    thd = (thd + dt * torque / inertia) / (1.0 + dt * damping / inertia)
    x[X_ARM_THD] = thd
    x[X_ARM_TH] = th + dt * thd


@jit
def plant_step(
    x: NDArray[np.float64],
    p: NDArray[np.float64],
    dt: float,
    torque_cmd: float,
    lag: float,
    arm_mode: int,
    arm_a: float,
    arm_b: float,
) -> None:
    """One plant step: motor, then arm, then the sheath node at the new positions."""
    motor_step(x, p, dt, torque_cmd, lag)
    ya_old = anchor_pull_m(p, x[X_ARM_TH])
    if arm_mode == ARM_PRESCRIBED:
        x[X_ARM_TH] = arm_a
        x[X_ARM_THD] = arm_b
    else:
        arm_step(x, p, dt, arm_a)
    th = x[X_ARM_TH]
    ya = anchor_pull_m(p, th)
    yda = moment_arm_m(p, th) * x[X_ARM_THD]
    sheath_step(x, p, dt, p[P_SPOOL_R] * x[X_SPOOL_Q] - sheath_shift_m(x, p, dt), ya, yda)
    x[X_W_ARM] += x[X_T_OUT] * (ya - ya_old)
    x[X_TIME] += dt


@jit
def impedance_torque(x: NDArray[np.float64], cmd: NDArray[np.float64]) -> float:
    """AK60-6 MIT-mode law ``τ = kp·(p_des − p) + kd·(v_des − v) + τ_ff`` (positions absolute here)."""
    return float(cmd[2] * (cmd[0] - x[X_SPOOL_Q]) + cmd[3] * (cmd[1] - x[X_SPOOL_W]) + cmd[4])


@jit
def integrate(
    x: NDArray[np.float64],
    p: NDArray[np.float64],
    h: NDArray[np.float64],
    dt: float,
    n_steps: int,
    motor_mode: int,
    cmd: NDArray[np.float64],
    arm_mode: int,
    arm_a: NDArray[np.float64],
    arm_b: NDArray[np.float64],
    record: NDArray[np.float64],
    stop_direction: int,
    stop_elevation: float,
) -> int:
    """Advance up to ``n_steps`` plant steps with a held motor command; row ``i`` of ``record`` gets
    the state after step ``i``. For ``ARM_HUMAN``, ``arm_a`` and ``arm_b`` hold unit normal draws
    for the motor noise and the lag's wander, and ``h`` the participant (``H_*``); for
    ``ARM_IMPEDANCE``, ``h`` holds the joint motor's command (``A_*``). With
    ``stop_direction`` +1 (−1) integration stops after the step where the elevation reaches
    ``stop_elevation`` from below (above); returns the steps done."""
    lag = 1.0 - math.exp(-dt / p[P_CURRENT_TAU])
    for i in range(n_steps):
        if motor_mode == MOTOR_TORQUE:
            torque = cmd[0]
        elif motor_mode == MOTOR_IMPEDANCE:
            torque = impedance_torque(x, cmd)
        elif motor_mode == MOTOR_TRAJECTORY:
            cmd[0] += cmd[1] * dt
            torque = impedance_torque(x, cmd)
        else:
            torque = 0.0
        if arm_mode == ARM_HUMAN:
            external = human_torque(x, p, h, dt, arm_a[i], arm_b[i])
            plant_step(x, p, dt, torque, lag, ARM_TORQUE, external, 0.0)
        elif arm_mode == ARM_IMPEDANCE:
            external = (h[A_KP] * (h[A_ELEVATION] - x[X_ARM_TH]) + h[A_KD] * (h[A_VELOCITY] - x[X_ARM_THD])
                        + h[A_FEEDFORWARD])
            external = min(max(external, -h[A_LIMIT]), h[A_LIMIT])
            plant_step(x, p, dt, torque, lag, ARM_TORQUE, external, 0.0)
        else:
            external = arm_a[i]
            plant_step(x, p, dt, torque, lag, arm_mode, arm_a[i], arm_b[i])
        record[i, R_TH] = x[X_ARM_TH]
        record[i, R_THD] = x[X_ARM_THD]
        record[i, R_T_OUT] = x[X_T_OUT]
        record[i, R_SPOOL_Q] = x[X_SPOOL_Q]
        record[i, R_SPOOL_W] = x[X_SPOOL_W]
        record[i, R_MOTOR_TAU] = x[X_MOTOR_TAU]
        record[i, R_ARM_TORQUE] = external
        record[i, R_REPORTED_TAU] = reported_torque_nm(x, p)
        if stop_direction != 0 and (x[X_ARM_TH] - stop_elevation) * stop_direction >= 0.0:
            return i + 1
    return n_steps


# --- virtual participant: parameter vector and torque ----------------------------------------------
H_LAG = 0  # s: the participant's movement trails the shown reference by this
H_OFFSET = 1  # rad: constant aim offset
H_AMPLITUDE = 2  # gain on the reference excursion above its low point
H_INERTIA_EST = 3  # kg·m²: the participant's estimate of the arm's inertia
H_GRAVITY_EST = 4  # Nm: estimate of the arm's gravity torque at 90° (with the hand load)
H_STIFFNESS = 5  # Nm/rad: impedance about the intended movement
H_DAMPING = 6  # Nm·s/rad
H_NOISE_CONST = 7  # Nm: constant part of the motor noise
H_NOISE_SIGNAL = 8  # fraction of the feedforward torque (signal-dependent motor noise)
H_NOISE_TAU = 9  # s: correlation time of the motor noise
H_REF_LOW = 10  # rad
H_REF_HIGH = 11  # rad
H_REF_MOVE_S = 12  # s: duration of one raising (or lowering) movement
H_REF_START = 13  # s: time the reference starts moving
H_REF_CYCLES = 14  # number of raise-and-lower cycles, then the reference rests at its low point
H_EXP_SUPPORT = 15  # expected assistance: support fraction of the controller's gravity torque
H_EXP_GRAVITY = 16  # Nm: the controller's gravity torque at 90° (anthropometric)
H_EXP_FLOOR_N = 17  # N: floor of the expected tension
H_EXP_ADAPT_S = 18  # s: time to learn the assistance after a condition change
H_COCON_GAIN = 19  # co-contraction torque built per Nm of feedback torque (Franklin et al. 2008)
H_COCON_TIME_S = 20  # s: time constant of building and relaxing co-contraction
H_COCON_STIFFNESS = 21  # 1/rad: joint stiffness added per Nm of co-contraction torque
H_LEARN_TIME_S = 22  # s: time constant of learning the torque its feedback keeps supplying (0: none)
H_LAG_SD = 23  # log-normal SD of the lag's slow wandering within a trial
H_LAG_TIME_S = 24  # s: correlation time of that wandering
H_EXCURSION_SD = 25  # log-normal SD of the excursion from one repetition to the next
N_HUMAN = 26  # then, optionally, one unit normal draw per repetition for its excursion
LEARNED_FRICTION_SPEED = 0.1  # rad/s: the friction-like basis is tanh(θ̇ / this)


@jit
def _minimum_jerk(tau: float) -> tuple[float, float, float]:
    """s, ds/dτ, d²s/dτ² of 10τ³ − 15τ⁴ + 6τ⁵ (Flash & Hogan 1985) for τ clipped to [0, 1]."""
    t = min(max(tau, 0.0), 1.0)
    s = t * t * t * (10.0 - 15.0 * t + 6.0 * t * t)
    ds = 30.0 * t * t * (1.0 - t) * (1.0 - t)
    dds = 60.0 * t * (1.0 - t) * (1.0 - 2.0 * t)
    return s, ds, dds


@jit
def reference_state(h: NDArray[np.float64], time_s: float) -> tuple[float, float, float]:
    """Elevation, velocity and acceleration of the shown raise-and-lower reference at ``time_s``."""
    low = h[H_REF_LOW]
    span = h[H_REF_HIGH] - low
    move = h[H_REF_MOVE_S]
    t = time_s - h[H_REF_START]
    if t <= 0.0 or t >= 2.0 * move * h[H_REF_CYCLES]:
        return low, 0.0, 0.0
    phase = t - 2.0 * move * math.floor(t / (2.0 * move))
    if phase < move:
        s, ds, dds = _minimum_jerk(phase / move)
        return low + span * s, span * ds / move, span * dds / (move * move)
    s, ds, dds = _minimum_jerk((phase - move) / move)
    return low + span * (1.0 - s), -span * ds / move, -span * dds / (move * move)


@jit
def repetition_excursion(h: NDArray[np.float64], time_s: float) -> float:
    """Factor on the excursion of the repetition the participant is in at (lagged) ``time_s``.

    Each repetition's peak differs (endpoint variability: Harris & Wolpert 1998, Nature 394:780;
    van Beers et al. 2004, J Neurophysiol 91:1050): a log-normal factor per repetition from the
    draws after ``N_HUMAN`` (none: 1). It changes at the low point, where the excursion is zero and
    the reference at rest, so the intended movement stays smooth.
    """
    draws = h.size - N_HUMAN
    if draws <= 0 or h[H_EXCURSION_SD] == 0.0:
        return 1.0
    cycle = 2.0 * h[H_REF_MOVE_S]
    repetition = math.floor((time_s - h[H_REF_START]) / cycle) if cycle > 0.0 else 0
    repetition = min(max(repetition, 0), draws - 1)
    return math.exp(h[H_EXCURSION_SD] * h[N_HUMAN + repetition])


@jit
def expected_assist_torque(p: NDArray[np.float64], h: NDArray[np.float64], th: float, time_s: float) -> float:
    """The assistance the participant expects: the controller's nominal law at the intended angle,
    ``r·max(T_floor, support·τ_g/r)``, learned over the first seconds of the condition."""
    if h[H_EXP_SUPPORT] <= 0.0 and h[H_EXP_FLOOR_N] <= 0.0:
        return 0.0
    r = moment_arm_m(p, th)
    nominal = max(h[H_EXP_FLOOR_N] * r, h[H_EXP_SUPPORT] * h[H_EXP_GRAVITY] * math.sin(th))
    learned = 1.0 - math.exp(-max(time_s, 0.0) / h[H_EXP_ADAPT_S])
    return float(nominal * learned)


@jit
def human_torque(
    x: NDArray[np.float64],
    p: NDArray[np.float64],
    h: NDArray[np.float64],
    dt: float,
    normal_draw: float,
    lag_draw: float,
) -> float:
    """Shoulder torque of the virtual participant (elevation > 0).

    The *planned* torque: inverse dynamics of the intended movement (the reference delayed by a
    wandering visuomotor lag, with aim offset and amplitude error) with the participant's own
    estimates of inertia and gravity, minus the assistance it expects from the suit. The
    *correction*: an impedance about the intended movement, stiffened by co-contraction, that turns
    unexpected cable tension into movement errors, plus what it has learned of such forces. Then
    motor noise (Harris & Wolpert 1998, Nature 394:780), a unit Ornstein–Uhlenbeck process scaled by
    the force of both sides' muscles. The correction and the co-contraction are left in ``x`` for
    the muscles (:mod:`bowden.sim.muscles`), which make them with the opposing muscles.
    """
    time_s = x[X_TIME]
    # Timing wanders slowly from cycle to cycle (an Ornstein–Uhlenbeck deviation of the lag).
    lag_decay = math.exp(-dt / h[H_LAG_TIME_S])
    x[X_LAG_NOISE] = lag_decay * x[X_LAG_NOISE] + math.sqrt(1.0 - lag_decay * lag_decay) * lag_draw
    lag = h[H_LAG] * math.exp(h[H_LAG_SD] * x[X_LAG_NOISE])
    ref, ref_d, ref_dd = reference_state(h, time_s - lag)
    low = h[H_REF_LOW]
    amp = h[H_AMPLITUDE] * repetition_excursion(h, time_s - lag)
    intended = low + amp * (ref - low) + h[H_OFFSET]
    intended_d = amp * ref_d
    intended_dd = amp * ref_dd
    # What the participant has learned about the suit (and its own arm): a gravity-like, a
    # friction-like and a viscous-like torque of the intended movement.
    basis_gravity = math.sin(intended)
    basis_friction = math.tanh(intended_d / LEARNED_FRICTION_SPEED)
    basis_viscous = intended_d
    learned = (
        x[X_LEARNED] * basis_gravity + x[X_LEARNED + 1] * basis_friction + x[X_LEARNED + 2] * basis_viscous
    )
    planned = (
        h[H_INERTIA_EST] * intended_dd
        + h[H_GRAVITY_EST] * basis_gravity
        - expected_assist_torque(p, h, intended, time_s)
    )
    th = x[X_ARM_TH]
    thd = x[X_ARM_THD]
    # Co-contraction stiffens the joint: muscle stiffness grows with muscle force (Hogan 1984,
    # IEEE TAC 29:681), so both sides pulling adds stiffness, with the damping ratio kept.
    cocontraction = x[X_COCONTRACTION]
    stiffening = 1.0 + h[H_COCON_STIFFNESS] * cocontraction / h[H_STIFFNESS]
    feedback = stiffening * (h[H_STIFFNESS] * (intended - th) + h[H_DAMPING] * (intended_d - thd))
    correction = feedback + learned
    x[X_CORRECTION] = correction
    # Errors build co-contraction and it relaxes without them (the V-shaped rule of Franklin et al.
    # 2008, J Neurosci 28:11165, here within a trial as a leaky integrator of the feedback's size).
    x[X_COCONTRACTION] += (1.0 - math.exp(-dt / h[H_COCON_TIME_S])) * (
        h[H_COCON_GAIN] * abs(feedback) - cocontraction
    )
    # Feedback-error learning (Kawato et al. 1987, Biol Cybern 57:169): the torque feedback keeps
    # supplying moves into the feedforward, on smooth functions of the intended movement (state-
    # dependent force fields are learned so, Shadmehr & Mussa-Ivaldi 1994, J Neurosci 14:3208).
    # Transients such as the tension spike at a reversal fit none of them and stay unlearned.
    if h[H_LEARN_TIME_S] > 0.0:
        rate = dt / h[H_LEARN_TIME_S] * feedback
        x[X_LEARNED] += rate * basis_gravity
        x[X_LEARNED + 1] += rate * basis_friction
        x[X_LEARNED + 2] += rate * basis_viscous
    decay = math.exp(-dt / h[H_NOISE_TAU])
    x[X_NOISE] = decay * x[X_NOISE] + math.sqrt(1.0 - decay * decay) * normal_draw
    # The noise grows with the force of each side's muscles (Harris & Wolpert), co-contraction and
    # corrections included, so a suit that is fought against makes the movement noisier.
    lifting = max(planned, 0.0) + max(correction, 0.0) + cocontraction
    lowering = max(-planned, 0.0) + max(-correction, 0.0) + cocontraction
    force = math.sqrt(lifting * lifting + lowering * lowering)
    noise = (h[H_NOISE_CONST] + h[H_NOISE_SIGNAL] * force) * x[X_NOISE]
    return float(planned + correction + noise)
