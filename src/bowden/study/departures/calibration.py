"""What the simulator was fitted to: which parameter was tuned to which of the paper's tables.

An outcome the simulator was tuned to reproduce is not evidence that the simulation reproduces the
paper: the departures section marks its rows "calibrated, not evidence". When a parameter of
``bowden.sim`` is tuned to a table of the paper, add an entry here (and say so in docs/simulation.md).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import pandas as pd

CALIBRATED = "calibrated, not evidence"


@dataclass(frozen=True)
class Calibration:
    """One tuning of the simulator against the paper.

    ``covers(family, outcome)`` says whether a departure row compares an outcome this tuning set;
    ``comparisons``, when given, narrows it to those rows of the outcome (e.g. only its
    ``"condition effect"``: the other comparisons of that outcome stay evidence).
    """

    parameter: str
    value: str
    fitted_to: str
    documented_in: str
    covers: Callable[[str, str], bool]
    comparisons: frozenset[str] | None = None

    def applies(self, family: str, outcome: str, comparison: str | None) -> bool:
        """Whether this tuning set the row (``comparison`` None: any row of the outcome)."""
        if not self.covers(family, outcome):
            return False
        return self.comparisons is None or comparison is None or comparison in self.comparisons


def _tracking(family: str, outcome: str) -> bool:
    return family == "tracking"


# The departure rows (study/departures/kinematics.py, table.py) whose outcomes the participants'
# constants were chosen to reproduce on seed 0 (docs/simulation.md, "Calibration").
_SPARC_CONDITION_OUTCOMES = frozenset(
    {"SPARC, condition effect", "SPARC, change from no suit", "SPARC, conditions compared (S5)"}
)
_ELEVATION_CONDITION_OUTCOMES = frozenset({
    "elevation RMSE, condition effect", "elevation RMSE, change from no suit",
    "elevation RMSE, conditions compared (S5)",
})
_RAISING_HEADLINES = frozenset({"Ant. delt., raising", "Trapezius, raising", "Pect. major, raising"})
# The condition tests of Table S7 whose p-values set the sEMG amplitude's repetition spread.
_DISPERSION_OUTCOMES = frozenset({"Post. delt., entire", "Biceps, entire", "Triceps, entire"})


CALIBRATIONS: tuple[Calibration, ...] = (
    Calibration(
        "sheath kinetic friction k, sheath viscous drag c_v, motor Coulomb friction τ_c",
        "0.10; 25 N·s/m; 0.08 Nm",
        "Table 1 (tab:torque_tension_tracking_RMSE_combined): the tension RMSE's growth with speed",
        "docs/simulation.md, 'How the sheath and motor friction and the wearer spread were chosen'; "
        "sim/parameters.py",
        _tracking,
    ),
    Calibration(
        "between-wearer spread of the sheath friction (log-normal SD)",
        "0.3",
        "Table 1: the 50 % tension RMSE's excess over pretension (5.1-5.5 N in quadrature)",
        "sim/participants.py, WEARER_FRICTION_LOG_SD; docs/simulation.md",
        _tracking,
    ),
    Calibration(
        "motor Coulomb friction τ_c (where the largest lowering error falls)",
        "0.08 Nm",
        "Table S3 (tab:peak_torque_percentage_errors_lowering): the pretension peak after the turn",
        "sim/parameters.py, coulomb_friction_nm; docs/simulation.md",
        lambda family, outcome: family == "peak errors" and outcome.startswith("time of peak, lowering"),
    ),
    Calibration(
        "visuomotor lag of the virtual participants (with the IMU's 50 ms latency)",
        "≈ 0.115 s",
        "Table S4 (tab:shoulder_kinematics_statistical_results): elevation RMSE per speed",
        "sim/participants.py, VirtualParticipant.visuomotor_lag_s",
        lambda family, outcome: family == "kinematics" and outcome.startswith("elevation RMSE, level"),
    ),
    Calibration(
        "the participants' motor noise: constant size and correlation time (simple and musculoskeletal "
        "muscles alike: it moves the arm)",
        "0.5 ± 0.1 Nm; 0.25 s",
        "Table S4 (tab:shoulder_kinematics_statistical_results): SPARC without the suit and its fall at "
        "50 % support (chosen by hand on seed 0, the tuning seed)",
        "sim/participants.py, motor_noise_nm, motor_noise_time_s; docs/simulation.md, 'Calibration'",
        lambda family, outcome: family == "kinematics" and outcome in _SPARC_CONDITION_OUTCOMES,
    ),
    Calibration(
        "practice (lag reduction and trials), the lag's trial and wander spreads, the per-repetition "
        "excursion spread",
        "5 % over 4 trials; 0.02, 0.3 (0.5 s); 0.05",
        "Table S4: no condition effect on the elevation RMSE (p = 0.335; chosen on seed 0)",
        "sim/participants.py, practice_*, lag_*, excursion_repetition_sd; docs/simulation.md, 'Calibration'",
        lambda family, outcome: family == "kinematics" and outcome in _ELEVATION_CONDITION_OUTCOMES,
    ),
    Calibration(
        "learning time constant and co-contraction time constant of the participants (the hand-made "
        "muscle model's corrections by the extensors)",
        "3 cycles; 1.5 s",
        "Table S9 (tab:iEMG_lower_mean) and S12: the posterior deltoid while lowering "
        "(+32 % at 50 %; chosen on seed 0)",
        "sim/participants.py, learning_cycles, cocontraction_time_s; docs/simulation.md, 'Calibration'",
        lambda family, outcome: family == "iEMG" and outcome == "Post. delt., lowering",
    ),
    Calibration(
        "the same noise, learning, co-contraction and practice constants, chosen while "
        "scripts/participant_calibration.py showed the raising iEMG at 50 % support",
        "as above",
        "Abstract and Table S8 (tab:iEMG_raise_mean): anterior deltoid, trapezius and "
        "pectoralis major while raising at 50 % (−30 / −38 / −38 %; seed 0)",
        "scripts/participant_calibration.py, PAPER_RAISING_50; docs/simulation.md, 'Calibration'",
        lambda family, outcome: family == "iEMG" and outcome in _RAISING_HEADLINES,
    ),
    Calibration(
        "sEMG amplitude's spread from repetition to repetition (log-normal SD per muscle; simple and "
        "musculoskeletal muscles alike)",
        "0.63",
        "Table S7 (tab:iEMG_whole_mean): the condition effects' p of the posterior deltoid (0.005), "
        "biceps (0.006) and triceps (0.061), which on 459 repetitions per condition imply a gamma "
        "dispersion phi ≈ 0.5 (no published cycle-to-cycle spread was found; chosen on seed 0)",
        "sim/participants.py, EMG_REPETITION_SD; docs/simulation.md, 'Amplitude variability'",
        lambda family, outcome: family == "iEMG" and outcome in _DISPERSION_OUTCOMES,
        frozenset({"condition effect"}),
    ),
    Calibration(
        "cuff-pressure weights of the Nordic neck and shoulder sites",
        "0.25-0.75 points per 10 N",
        "Results, Questionnaires: discomfort at the neck and right shoulder grows with support",
        "sim/questionnaires.py",
        lambda family, outcome: family == "questionnaires" and outcome.startswith("Nordic"),
    ),
    Calibration(
        "the cohort's anthropometrics (an input, not an outcome)",
        "17 adults, 12 women, stature 1.70 ± 0.11 m, mass 63.2 ± 11.5 kg",
        "Results, first paragraph (cohort)",
        "sim/participants.py, PAPER_*",
        lambda family, outcome: False,
    ),
)


def calibrated(family: str, outcome: str, comparison: str | None = None) -> bool:
    """True if a departure row of this family, outcome and comparison compares a value the simulator
    was fitted to (``comparison`` None: any comparison of the outcome)."""
    return any(entry.applies(family, outcome, comparison) for entry in CALIBRATIONS)


def calibration_table() -> pd.DataFrame:
    """The calibrations, one row each, for the report."""
    rows = [
        {"parameter": e.parameter, "value": e.value, "fitted to": e.fitted_to,
         "documented in": e.documented_in}
        for e in CALIBRATIONS
    ]
    return pd.DataFrame(rows)
