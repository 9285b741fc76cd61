"""The paper's electrodes from MoBL's muscles: the one electrode mapping of the musculoskeletal model.

The paper's electrodes are mapped to MoBL's muscles (:data:`ELECTRODES`): anterior, medial and
posterior deltoid to DELT1, DELT2, DELT3; the clavicular pectoralis major to PECM1; biceps to
BIClong; triceps to TRIlong; latissimus dorsi to LAT1–3 (their mean weighted by maximal force).

**Trapezius**: MoBL has none — its scapula follows the humerus by constraint, not by muscles. The
upper trapezius and the deltoid act together as the force couple that elevates the arm and upwardly
rotates the scapula (Inman, Saunders & Abbott 1944, J Bone Joint Surg 26:1): the trapezius
electrode is represented by the unweighted mean of DELT1 and DELT2 (a proxy, not a mechanical
result).

:func:`solve_state` is the single-state path (MuJoCo at that state: inverse dynamics of the humeral
motion with the hand load and the cable's tension, :meth:`MyoArm.required_torques_nm`, less the
muscles' passive forces, then :func:`solve_static` over the shoulder and elbow muscles); the study
path (:mod:`~bowden.sim.musculoskeletal.trial`) solves a trial's states from the table and maps them
with the same :func:`electrode_activations`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from bowden.contracts import MUSCLES
from bowden.model import CuffGeometry
from bowden.sim.musculoskeletal.myoarm import ARM_MUSCLES, COORDINATES, ELBOW, MyoArm, recruitable
from bowden.sim.musculoskeletal.static_optimisation import StaticSolution, solve_static

ELECTRODES: dict[str, tuple[str, ...]] = {
    "anterior_deltoid": ("DELT1",),
    "medial_deltoid": ("DELT2",),
    "posterior_deltoid": ("DELT3",),
    "biceps": ("BIClong",),
    "triceps": ("TRIlong",),
    "latissimus_dorsi": ("LAT1", "LAT2", "LAT3"),
    "pectoralis_major": ("PECM1",),
    "trapezius": ("DELT1", "DELT2"),  # proxy: see the module's docstring
}
# Electrodes whose MoBL muscles are averaged without weights (a proxy, not a muscle's share of force).
UNWEIGHTED = frozenset({"trapezius"})


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
    capacity = recruitable(state.moment_arm_m * state.active_force_n[None, :])
    return solve_static(capacity, required - passive)


def electrode_activations(
    activations: NDArray[np.float64], max_force_n: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The paper's eight muscles (order of ``contracts.MUSCLES``) from MoBL's.

    Parameters
    ----------
    activations
        Shape (..., muscles): activations of :data:`ARM_MUSCLES` (one state or many).
    max_force_n
        Shape (muscles,): their maximal isometric forces (:attr:`MyoArm.max_force_n`), N, the
        weights of an electrode over several muscles (LAT1–3).

    Returns
    -------
    Shape (..., 8): force-weighted means of each electrode's muscles (unweighted for the
    trapezius proxy).
    """
    activations = np.asarray(activations, dtype=np.float64)
    out = np.zeros((*activations.shape[:-1], len(MUSCLES)))
    # Weighted sums column by column, not a matrix product: BLAS's threads, woken for a product this
    # small, spin on the other core afterwards and cost a study's workers more than the product.
    for m, muscle in enumerate(MUSCLES):
        index = [ARM_MUSCLES.index(name) for name in ELECTRODES[muscle]]
        share = np.ones(len(index)) if muscle in UNWEIGHTED else np.asarray(max_force_n)[index]
        for i, weight in zip(index, share / share.sum(), strict=True):
            out[..., m] += weight * activations[..., i]
    return out
