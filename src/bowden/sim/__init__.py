"""The simulated suit: plant physics, mannequin bench, virtual participants and batch simulation.

* :class:`SimulatedSuit` — one suit and one arm driver behind the hardware protocols (``motor``,
  ``elevation_sensor``, ``tension_sensor``, ``clock``), with ``advance_to`` and ``true_state``.
* :func:`run_bench` — the paper's identification protocol on a mannequin → bench recording.
* :func:`generate_cohort` — virtual participants drawn like the paper's cohort.
* :func:`simulate_cohort` / :func:`simulate_trial` — the whole study protocol with the paper's
  controller, returning :class:`CohortSimulation` / :class:`TrialSimulation`.

The physics and its sources are in :mod:`bowden.sim._kernels` and :mod:`bowden.sim.parameters`;
``docs/simulation.md`` explains the model and compares the simulated study with the paper.
"""

from bowden.sim.arm import MannequinArm, ParticipantArm, PrescribedArm
from bowden.sim.batch import ProtocolSettings, simulate_cohort, simulate_trial
from bowden.sim.bench import BenchProtocol, run_bench
from bowden.sim.emg import emg_synthesize
from bowden.sim.muscles import muscle_activations
from bowden.sim.parameters import (
    ArmParameters,
    ImuParameters,
    LoadCellParameters,
    MotorParameters,
    SheathParameters,
    SuitParameters,
    TransmissionParameters,
)
from bowden.sim.participants import ExpectedAssistance, VirtualParticipant, generate_cohort
from bowden.sim.plant import Plant, PlantState
from bowden.sim.results import CohortSimulation, TrialSimulation
from bowden.sim.suit import SimulatedSuit

__all__ = [
    "ArmParameters",
    "BenchProtocol",
    "CohortSimulation",
    "ExpectedAssistance",
    "ImuParameters",
    "LoadCellParameters",
    "MannequinArm",
    "MotorParameters",
    "ParticipantArm",
    "Plant",
    "PlantState",
    "PrescribedArm",
    "ProtocolSettings",
    "SheathParameters",
    "SimulatedSuit",
    "SuitParameters",
    "TransmissionParameters",
    "TrialSimulation",
    "VirtualParticipant",
    "emg_synthesize",
    "generate_cohort",
    "muscle_activations",
    "run_bench",
    "simulate_cohort",
    "simulate_trial",
]
