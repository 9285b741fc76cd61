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

from typing import TYPE_CHECKING

from bowden._lazy import lazy_exports

# Imported on first use (PEP 562): the suit's own process imports bowden.sim.link and the peers, and
# should not pay for the batch simulation's SciPy and pandas (a second of start-up per simulated suit).
_EXPORTS = {
    "ArmParameters": "bowden.sim.parameters",
    "BenchProtocol": "bowden.sim.bench",
    "CohortSimulation": "bowden.sim.results",
    "ExpectedAssistance": "bowden.sim.participants",
    "ImuParameters": "bowden.sim.parameters",
    "LoadCellParameters": "bowden.sim.parameters",
    "MannequinArm": "bowden.sim.arm",
    "MotorParameters": "bowden.sim.parameters",
    "ParticipantArm": "bowden.sim.arm",
    "Plant": "bowden.sim.plant",
    "PlantState": "bowden.sim.plant",
    "PrescribedArm": "bowden.sim.arm",
    "ProtocolSettings": "bowden.sim.batch",
    "SheathParameters": "bowden.sim.parameters",
    "SimulatedSuit": "bowden.sim.suit",
    "SuitParameters": "bowden.sim.parameters",
    "TransmissionParameters": "bowden.sim.parameters",
    "TrialSimulation": "bowden.sim.results",
    "VirtualParticipant": "bowden.sim.participants",
    "emg_synthesize": "bowden.sim.emg",
    "generate_cohort": "bowden.sim.participants",
    "muscle_activations": "bowden.sim.muscles",
    "run_bench": "bowden.sim.bench",
    "simulate_cohort": "bowden.sim.batch",
    "simulate_trial": "bowden.sim.batch",
}

if TYPE_CHECKING:
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


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)


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
