"""Elevation tracking RMSE and SPARC as published: Supplementary Tables S4
(tab:shoulder_kinematics_statistical_results), S5 (tab:shoulder_kinematics_condition_comparisons) and
S6 (tab:shoulder_kinematics_velocity_comparisons). SPARC has its sign flipped to positive, as the paper
reports it (larger = less smooth).
"""

from __future__ import annotations

import pandas as pd

from bowden.errors import ParameterError
from bowden.study.paper_values.kinematics_data import (
    KINEMATICS,
    KINEMATICS_CONDITION_PAIRS,
    KINEMATICS_P,
    KINEMATICS_SPEED_PAIRS,
)
from bowden.study.paper_values.pvalue import P

OUTCOMES = ("elevation_rmse_deg", "sparc")
TERMS = ("condition", "speed", "interaction")


def kinematics() -> pd.DataFrame:
    """Mean and SD per outcome, speed and condition (Table S4).

    Tidy: outcome, speed, condition, mean, spread (the bracketed value as published).
    """
    rows = [(o, s, c, mean, sd) for (o, s, c), (mean, sd) in KINEMATICS.items()]
    return pd.DataFrame(rows, columns=["outcome", "speed", "condition", "mean", "spread"])


def kinematics_p(outcome: str) -> dict[str, P]:
    """GLMM p-values of condition, speed and their interaction (Table S4)."""
    if outcome not in KINEMATICS_P:
        raise ParameterError(f"outcome must be one of {OUTCOMES}, got {outcome!r}")
    return dict(zip(TERMS, KINEMATICS_P[outcome], strict=True))


def kinematic_pairs(factor: str) -> pd.DataFrame:
    """Pairwise comparisons: change first − second, its SE and p (Table S5 conditions, S6 speeds).

    The paper compared conditions for SPARC only: elevation RMSE had no significant condition effect,
    so Table S5 reads N/A for it and it has no rows here.
    """
    if factor not in ("condition", "speed"):
        raise ParameterError(f"factor must be 'condition' or 'speed', got {factor!r}")
    source = KINEMATICS_CONDITION_PAIRS if factor == "condition" else KINEMATICS_SPEED_PAIRS
    rows = [(o, a, b, change, se, p) for (o, a, b), (change, se, p) in source.items()]
    return pd.DataFrame(rows, columns=["outcome", "first", "second", "change", "se", "p"])


# GLMM p-values of Table S4 as printed (C, V, C×V); "< 0.001" is a bound (see P).
KINEMATICS_P_VALUES = {outcome: kinematics_p(outcome) for outcome in OUTCOMES}
