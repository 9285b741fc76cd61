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

    ``covers(family, outcome)`` says whether a departure row compares an outcome this tuning set.
    """

    parameter: str
    value: str
    fitted_to: str
    documented_in: str
    covers: Callable[[str, str], bool]


def _tracking(family: str, outcome: str) -> bool:
    return family == "tracking"


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


def calibrated(family: str, outcome: str) -> bool:
    """True if a departure row of this family and outcome compares a value the simulator was fitted to."""
    return any(entry.covers(family, outcome) for entry in CALIBRATIONS)


def calibration_table() -> pd.DataFrame:
    """The calibrations, one row each, for the report."""
    rows = [
        {"parameter": e.parameter, "value": e.value, "fitted to": e.fitted_to,
         "documented in": e.documented_in}
        for e in CALIBRATIONS
    ]
    return pd.DataFrame(rows)
