"""Activations of the paper's recorded muscles from MyoArm's mechanics at one state of the arm.

Inverse dynamics of the humeral motion with the hand load and the cable's tension
(:meth:`MyoArm.required_torques_nm`), less the muscles' passive forces, then static optimisation
(:func:`solve_static`) over the shoulder and elbow muscles. The paper's electrodes are mapped to
MoBL's muscles: anterior, medial and posterior deltoid to DELT1, DELT2, DELT3; the clavicular
pectoralis major to PECM1; biceps to BIClong; triceps to TRIlong; latissimus dorsi to LAT1–3
(their mean weighted by maximal force). The trapezius has no counterpart: MoBL moves the scapula
by the rhythm's constraints, not by muscles, so it is not computed here (NaN).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from bowden.contracts import MUSCLES
from bowden.model import CuffGeometry
from bowden.sim.musculoskeletal.myoarm import ARM_MUSCLES, COORDINATES, ELBOW, MyoArm
from bowden.sim.musculoskeletal.static_optimisation import StaticSolution, solve_static

ELECTRODES: dict[str, tuple[str, ...]] = {
    "anterior_deltoid": ("DELT1",),
    "medial_deltoid": ("DELT2",),
    "posterior_deltoid": ("DELT3",),
    "biceps": ("BIClong",),
    "triceps": ("TRIlong",),
    "latissimus_dorsi": ("LAT1", "LAT2", "LAT3"),
    "pectoralis_major": ("PECM1",),
}


def solve_state(
    arm: MyoArm,
    elevation_rad: float,
    velocity_rad_s: float,
    acceleration_rad_s2: float,
    *,
    hand_load_kg: float,
    cable_tension_n: float = 0.0,
    geometry: CuffGeometry | None = None,
) -> StaticSolution:
    """Static optimisation at one state: activations of :data:`ARM_MUSCLES` and the reserves."""
    state = arm.muscle_state(elevation_rad, velocity_rad_s)
    required = arm.required_torques_nm(
        elevation_rad, velocity_rad_s, acceleration_rad_s2, hand_load_kg=hand_load_kg,
        cable_tension_n=cable_tension_n, geometry=geometry,
    )
    # The elbow is held fully extended, at MoBL's extension stop (elbow_flexion_r = 0): a load that
    # would hyperextend it (a flexing torque required) is borne by the joint, not by the flexors.
    elbow = COORDINATES.index(ELBOW)
    required[elbow] = min(required[elbow], 0.0)
    passive = state.moment_arm_m @ state.passive_force_n
    capacity = state.moment_arm_m * state.active_force_n[None, :]
    return solve_static(capacity, required - passive)


def electrode_activations(arm: MyoArm, activations: NDArray[np.float64]) -> NDArray[np.float64]:
    """The paper's eight muscles (order of ``contracts.MUSCLES``) from MoBL's; NaN for the trapezius."""
    force = np.array([arm.model.actuator_gainprm[i][2] for i in arm.muscle_ids])
    out = np.full(len(MUSCLES), math.nan)
    for m, muscle in enumerate(MUSCLES):
        names = ELECTRODES.get(muscle)
        if names is None:
            continue
        index = [ARM_MUSCLES.index(name) for name in names]
        out[m] = float(np.average(activations[index], weights=force[index]))
    return out
