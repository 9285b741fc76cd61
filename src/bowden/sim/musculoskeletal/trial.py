"""A trial's muscle activations from MyoArm's mechanics (``--muscles musculoskeletal``).

Per control cycle: inverse dynamics of the trial's true humeral motion (elevation, velocity and
the acceleration differentiated from it) with the participant's hand load and the cable's true
tension, from the participant-scaled :mod:`~bowden.sim.musculoskeletal.table`; then static
optimisation (least Σ a², :func:`solve_static_batch`) with one more row, **co-contraction**: the
extensors about the elevation (the muscles whose capacity there is negative: DELT3, LAT1–3,
TRIlong, TMAJ, …) must make the participant's co-contraction torque plus its downward
corrections, and the flexors the net torque on top. Least Σ a² alone never activates an
antagonist (Crowninshield & Brand 1981), yet people stiffen the joint against errors by
co-contracting (Franklin et al. 2008, J Neurosci 28:11165: the participant's
``cocontraction_nm``), and a downward correction comes from the stretched extensors even while the
flexors hold the arm up (Pruszynski & Scott 2012, Exp Brain Res 218:341: its
``correction_torque_nm`` < 0). Both signals come from the participant's own control in the batch
kernel; nothing is tuned here.

**Scaling to the participant**: MyoArm's arm weighs 3.78 kg, 4.94 % of a 76.5 kg man by de Leva's
segment fractions (1996, J Biomech 29:1223: upper arm 2.71 %, forearm 1.62 %, hand 0.61 %). The
arm's gravity and velocity torques scale with the participant's body mass over that and its
``gravity_scale``, its inertia with ``inertia_scale``; muscle forces with the body mass (the simple
model's strength, 0.7 Nm/kg, is proportional to it too). Lengths are MyoArm's (not scaled).

**Electrodes**: :func:`~bowden.sim.musculoskeletal.activations.electrode_activations`, the one
mapping (with the trapezius proxy) that the single-state path uses too.

The solve runs at 100 Hz (activation dynamics, 15/50 ms, smooth faster changes anyway) and is
interpolated to the control cycles before activation dynamics.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from bowden.contracts import MUSCLES
from bowden.sim.muscles import ACTIVATION_TIME_S, DEACTIVATION_TIME_S, activation_dynamics
from bowden.sim.musculoskeletal.activations import electrode_activations
from bowden.sim.musculoskeletal.myoarm import COORDINATES, ELBOW, ELEVATION, recruitable
from bowden.sim.musculoskeletal.static_optimisation import solve_static_batch
from bowden.sim.musculoskeletal.table import MechanicsTable, interpolate, load_table
from bowden.sim.participants import VirtualParticipant

DE_LEVA_ARM_FRACTION = 0.0271 + 0.0162 + 0.0061  # upper arm, forearm, hand of body mass (men)
SOLVE_RATE_HZ = 100.0


def cocontraction_row(capacity_nm: NDArray[np.float64]) -> NDArray[np.float64]:
    """The extensors' torque against elevation at full activation (states, muscles), ≥ 0."""
    elevation = capacity_nm[:, COORDINATES.index(ELEVATION), :]
    return np.where(elevation < 0.0, -elevation, 0.0)


def required_and_capacity(
    table: MechanicsTable,
    participant: VirtualParticipant,
    elevation_rad: NDArray[np.float64],
    velocity_rad_s: NDArray[np.float64],
    acceleration_rad_s2: NDArray[np.float64],
    tension_n: NDArray[np.float64],
    cocontraction_nm: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Static optimisation's inputs: capacity (states, coordinates + 1, muscles), required (states, +1)."""
    fields = interpolate(table, elevation_rad, velocity_rad_s)
    body_scale = participant.subject.mass_kg * DE_LEVA_ARM_FRACTION / float(table.arm_mass_kg)
    required = (
        body_scale * participant.gravity_scale * fields["arm"]
        + body_scale * participant.inertia_scale * acceleration_rad_s2[:, None] * fields["inertia"]
        + participant.hand_load_kg * fields["hand"]
        + tension_n[:, None] * fields["cable"]
    )
    # The elbow rests at its extension stop: a load that would hyperextend it is borne by the joint.
    elbow = COORDINATES.index(ELBOW)
    required[:, elbow] = np.minimum(required[:, elbow], 0.0)
    capacity = recruitable(body_scale * fields["capacity"])
    required = required - body_scale * fields["passive"]
    capacity = np.concatenate([capacity, cocontraction_row(capacity)[:, None, :]], axis=1)
    required = np.concatenate([required, np.maximum(cocontraction_nm, 0.0)[:, None]], axis=1)
    return capacity, required


def trial_activations(
    participant: VirtualParticipant,
    signals: Mapping[str, NDArray[np.float64]],
    *,
    sample_rate_hz: float,
    elevation: str,
    velocity: str,
    tension: str,
    correction: str,
    cocontraction: str,
) -> NDArray[np.float64]:
    """Activations (cycles, 8) of a trial's control cycles; the signal names are the trial's."""
    table = load_table()
    theta = np.asarray(signals[elevation], dtype=np.float64)
    velocity_rad_s = np.asarray(signals[velocity], dtype=np.float64)
    acceleration = np.gradient(velocity_rad_s) * sample_rate_hz
    stride = max(1, round(sample_rate_hz / SOLVE_RATE_HZ))
    picked = np.arange(0, theta.size, stride)
    if picked[-1] != theta.size - 1:
        picked = np.append(picked, theta.size - 1)
    # Acceleration averaged over the solve interval: differentiated velocity is noisy sample to sample.
    kernel = np.ones(stride) / stride
    acceleration = np.convolve(acceleration, kernel, mode="same")
    tension_n = np.nan_to_num(np.asarray(signals[tension], dtype=np.float64)[picked], nan=0.0)
    stiffening = np.asarray(signals[cocontraction], dtype=np.float64)[picked]
    downward = np.maximum(-np.asarray(signals[correction], dtype=np.float64)[picked], 0.0)
    capacity, required = required_and_capacity(
        table, participant, theta[picked], velocity_rad_s[picked], acceleration[picked],
        np.maximum(tension_n, 0.0), stiffening + downward,
    )
    solution = solve_static_batch(capacity, required)
    electrodes = electrode_activations(solution.activations, table.max_force_n)
    cycles = np.arange(theta.size)
    excitation = np.column_stack([np.interp(cycles, picked, electrodes[:, m]) for m in range(len(MUSCLES))])
    return activation_dynamics(np.clip(excitation, 0.0, 1.0), 1.0 / sample_rate_hz,
                               ACTIVATION_TIME_S, DEACTIVATION_TIME_S)
