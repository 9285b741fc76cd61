"""The plant as an object: parameters packed for the compiled step, state, and the true state for tests.

:class:`Plant` is the physics without sensors or protocols; :class:`bowden.sim.SimulatedSuit` wraps
it with the hardware protocols, and the batch simulation drives many plants in compiled loops.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from bowden.errors import ParameterError
from bowden.sim import _kernels as k
from bowden.sim.parameters import ArmParameters, SuitParameters

# Soft joint stops of the arm: stiff enough to hold a 0.6 kg·m² arm within a few degrees of the stop
# against its own weight, slow enough (≈ 20 rad/s) to be far from the step's stability limit.
STOP_STIFFNESS_NM_RAD = 200.0
STOP_DAMPING_NMS_RAD = 5.0


def pack_parameters(suit: SuitParameters, arm: ArmParameters) -> NDArray[np.float64]:
    """The compiled step's parameter vector (indices ``P_*`` of :mod:`bowden.sim._kernels`)."""
    if arm.max_elevation_rad >= suit.geometry.rest_angle_rad - math.radians(5.0):
        raise ParameterError(
            "ArmParameters.max_elevation_rad must stay 5° below CuffGeometry.rest_angle_rad, where the "
            "cable line passes through the shoulder"
        )
    p = np.zeros(k.N_PARAM)
    m, s, t, g = suit.motor, suit.sheath, suit.transmission, suit.geometry
    p[k.P_SPOOL_R] = m.spool_radius_m
    p[k.P_MOTOR_J] = m.rotor_inertia_kgm2
    p[k.P_MOTOR_COULOMB] = m.coulomb_friction_nm
    p[k.P_MOTOR_VISCOUS] = m.viscous_friction_nms_rad
    p[k.P_CURRENT_TAU] = m.current_loop_time_constant_s
    p[k.P_KT_RATIO] = m.torque_constant_ratio
    p[k.P_TORQUE_LIMIT] = m.torque_limit_nm
    p[k.P_K_KINETIC] = s.kinetic_coefficient
    p[k.P_K_STATIC] = s.static_coefficient
    p[k.P_V_STRIBECK] = s.stribeck_velocity_m_s
    p[k.P_V_STICK] = s.stick_velocity_m_s
    p[k.P_SHEATH_VISCOUS] = s.viscous_coefficient_ns_m
    p[k.P_K_CABLE] = t.cable_stiffness_n_m
    p[k.P_K_DISTAL] = t.distal_stiffness_n_m
    p[k.P_C_DISTAL] = t.distal_damping_ns_m
    p[k.P_GEOM_A] = g.exit_distance_m
    p[k.P_GEOM_B] = g.anchor_distance_m
    p[k.P_GEOM_PSI] = g.rest_angle_rad
    p[k.P_ARM_I] = arm.inertia_kgm2
    p[k.P_ARM_G] = arm.gravity_torque_nm
    p[k.P_ARM_DAMPING] = arm.damping_nms_rad
    p[k.P_ARM_MIN] = arm.min_elevation_rad
    p[k.P_ARM_MAX] = arm.max_elevation_rad
    p[k.P_STOP_K] = STOP_STIFFNESS_NM_RAD
    p[k.P_STOP_C] = STOP_DAMPING_NMS_RAD
    v = suit.structure
    p[k.P_PRESLIDE_M] = v.presliding_m
    p[k.P_STRIBECK_EXP] = v.stribeck_exponent
    p[k.P_VISCOUS_LOAD] = v.viscous_per_newton_ns_m_n
    p[k.P_WRAP_GAIN] = v.wrap_gain_per_rad
    p[k.P_TENSION_GAIN] = v.tension_gain_per_n
    p[k.P_PLAY_M] = v.play_m
    p[k.P_PLAY_COMPLIANCE] = v.play_compliance_m_n
    p[k.P_SHEATH_COMPLIANCE] = v.sheath_compliance_m_n
    p[k.P_KT_TEMPCO] = v.kt_tempco_per_k
    p[k.P_HEATING] = v.heating_k_nm2
    p[k.P_THERMAL_TAU] = v.thermal_time_constant_s
    return p


def equilibrium_state(
    p: NDArray[np.float64], elevation_rad: float, tension_n: float
) -> NDArray[np.float64]:
    """A state at rest: arm at ``elevation_rad``, both cable segments at ``tension_n``, sheath stuck,
    motor delivering the torque that holds that tension."""
    if not (math.isfinite(tension_n) and tension_n >= 0.0):
        raise ParameterError(f"initial tension must be >= 0 N (a cable cannot push), got {tension_n!r}")
    x = np.zeros(k.N_STATE)
    ya = float(k.anchor_pull_m(p, elevation_rad))
    s = ya + tension_n / p[k.P_K_DISTAL]
    x[k.X_NODE_S] = s
    # A compliant sheath is compressed by the tension it holds (its play is not taken up at rest).
    x[k.X_SHEATH_SHIFT] = p[k.P_SHEATH_COMPLIANCE] * tension_n
    x[k.X_SPOOL_Q] = (s + tension_n / p[k.P_K_CABLE] + x[k.X_SHEATH_SHIFT]) / p[k.P_SPOOL_R]
    x[k.X_MOTOR_TAU] = p[k.P_SPOOL_R] * tension_n
    x[k.X_STUCK] = 1.0
    x[k.X_SLIP_DIR] = 1.0
    x[k.X_ARM_TH] = elevation_rad
    x[k.X_T_IN] = tension_n
    x[k.X_T_OUT] = tension_n
    x[k.X_DISTAL_STRETCH] = tension_n / p[k.P_K_DISTAL]
    return x


@dataclass(frozen=True, slots=True)
class PlantState:
    """The true state of the simulated suit (what no sensor sees exactly).

    Tensions in N, energies in J (cumulative since the start), angles in rad, velocities in rad/s
    or m/s. ``motor_torque_nm`` is the torque the motor really delivers (after the current-loop lag,
    torque-constant error and limit).
    """

    time_s: float
    anchor_tension_n: float
    sheath_entry_tension_n: float
    elevation_rad: float
    elevation_velocity_rad_s: float
    spool_angle_rad: float
    spool_velocity_rad_s: float
    motor_torque_nm: float
    sheath_stuck: bool
    sheath_slip_velocity_m_s: float
    sheath_dissipated_j: float
    distal_damper_dissipated_j: float
    motor_friction_dissipated_j: float
    spool_work_j: float
    arm_work_j: float
    distal_stretch_m: float

    @classmethod
    def from_vector(cls, x: NDArray[np.float64]) -> PlantState:
        return cls(
            time_s=float(x[k.X_TIME]),
            anchor_tension_n=float(x[k.X_T_OUT]),
            sheath_entry_tension_n=float(x[k.X_T_IN]),
            elevation_rad=float(x[k.X_ARM_TH]),
            elevation_velocity_rad_s=float(x[k.X_ARM_THD]),
            spool_angle_rad=float(x[k.X_SPOOL_Q]),
            spool_velocity_rad_s=float(x[k.X_SPOOL_W]),
            motor_torque_nm=float(x[k.X_MOTOR_TAU]),
            sheath_stuck=bool(x[k.X_STUCK] > 0.5),
            sheath_slip_velocity_m_s=float(x[k.X_SLIP_V]),
            sheath_dissipated_j=float(x[k.X_E_SHEATH]),
            distal_damper_dissipated_j=float(x[k.X_E_DISTAL]),
            motor_friction_dissipated_j=float(x[k.X_E_MOTOR]),
            spool_work_j=float(x[k.X_W_SPOOL]),
            arm_work_j=float(x[k.X_W_ARM]),
            distal_stretch_m=float(x[k.X_DISTAL_STRETCH]),
        )

    def elastic_energy_j(self, parameters: SuitParameters) -> float:
        """Energy stored in the two cable segments (only a taut segment stores any): ½T_in²/k_c on the
        motor side, ½k_d·e² distal (its tension also carries the damper's force)."""
        t = parameters.transmission
        stored_in = 0.5 * self.sheath_entry_tension_n**2 / t.cable_stiffness_n_m
        stretch = max(0.0, self.distal_stretch_m)
        return stored_in + 0.5 * t.distal_stiffness_n_m * stretch**2


class Plant:
    """One suit's physics: fixed-step integration of the compiled plant.

    Parameters
    ----------
    parameters
        The suit.
    arm
        The arm the cable pulls on (mannequin or human arm parameters).
    elevation_rad, tension_n
        Initial equilibrium: arm angle and cable tension (sheath stuck, motor holding it).
    """

    def __init__(
        self,
        parameters: SuitParameters,
        arm: ArmParameters,
        *,
        elevation_rad: float,
        tension_n: float,
    ) -> None:
        self.parameters = parameters
        self.arm = arm
        self.vector = pack_parameters(parameters, arm)
        self.state_vector = equilibrium_state(self.vector, elevation_rad, tension_n)
        self.steps_done = 0

    @property
    def substep_s(self) -> float:
        return self.parameters.substep_s

    def integrate(
        self,
        n_steps: int,
        *,
        motor_mode: int,
        command: NDArray[np.float64],
        arm_mode: int,
        arm_a: NDArray[np.float64],
        arm_b: NDArray[np.float64],
        human: NDArray[np.float64] | None = None,
        stop_direction: int = 0,
        stop_elevation_rad: float = 0.0,
    ) -> NDArray[np.float64]:
        """Advance ``n_steps`` steps; returns the per-step record (columns ``R_*`` of the kernels).

        With ``stop_direction`` +1 (−1) it stops early, after the step where the elevation reaches
        ``stop_elevation_rad`` from below (above); the record then has fewer rows."""
        record = np.empty((n_steps, k.N_RECORD))
        if n_steps <= 0:
            return record
        h = human if human is not None else np.zeros(k.N_HUMAN)
        done = k.integrate(
            self.state_vector,
            self.vector,
            h,
            self.substep_s,
            n_steps,
            motor_mode,
            np.ascontiguousarray(command, dtype=np.float64),
            arm_mode,
            np.ascontiguousarray(arm_a, dtype=np.float64),
            np.ascontiguousarray(arm_b, dtype=np.float64),
            record,
            stop_direction,
            stop_elevation_rad,
        )
        self.steps_done += done
        return record[:done]

    def state(self) -> PlantState:
        return PlantState.from_vector(self.state_vector)
