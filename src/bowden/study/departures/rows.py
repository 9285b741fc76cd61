"""One comparison of a study's outcome with the paper's: the row every departures table is made of.

A row is flagged where the direction differs (both values farther from zero than the family's dead
zone), where the size differs by more than the family's tolerance, or where one finds the effect
significant (p < 0.05) and the other does not. Rows of outcomes the simulator was tuned to are marked
:data:`~bowden.study.departures.calibration.CALIBRATED` (:mod:`bowden.study.departures.calibration`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from bowden.study.departures.calibration import CALIBRATED, calibrated
from bowden.study.paper_values import P

ALPHA = 0.05
COLUMNS = (
    "family", "outcome", "comparison", "unit", "study", "paper", "tolerance",
    "study p", "paper p", "departs in", "evidence",
)


@dataclass(frozen=True)
class Tolerance:
    """How close a value must be to the paper's to count as the same size, and the zero band.

    ``size`` is in the row's unit (nan: the paper gives no size to compare); changes within
    ``dead_zone`` of zero have no direction to disagree about; ``direction`` False for levels (an
    RMSE has no direction).
    """

    size: float
    dead_zone: float = 0.0
    direction: bool = True


def comparison_row(
    *,
    family: str,
    outcome: str,
    comparison: str,
    unit: str,
    study: float,
    paper: float | str,
    tolerance: Tolerance,
    study_p: float = math.nan,
    paper_p: P | None = None,
) -> dict[str, object]:
    """A departures row: both values, both p-values and what differs.

    ``paper`` is a number, or where the paper gives only a direction, ``"increase"``/``"decrease"``
    (compared in direction only) or ``"no change"`` (compared in significance only).
    """
    flags = []
    if isinstance(paper, str):
        sign = {"increase": 1.0, "decrease": -1.0}.get(paper, 0.0)
        if sign and math.isfinite(study) and abs(study) > tolerance.dead_zone and np.sign(study) != sign:
            flags.append("direction")
    elif math.isfinite(study) and math.isfinite(paper):
        if (
            tolerance.direction
            and min(abs(study), abs(paper)) > tolerance.dead_zone
            and np.sign(study) != np.sign(paper)
        ):
            flags.append("direction")
        if math.isfinite(tolerance.size) and abs(study - paper) > tolerance.size:
            flags.append("size")
    if math.isfinite(study_p) and paper_p is not None and (study_p < ALPHA) != paper_p.significant(ALPHA):
        flags.append("significance")
    no_data = not math.isfinite(study) and not math.isfinite(study_p)
    return {
        "family": family,
        "outcome": outcome,
        "comparison": comparison,
        "unit": unit,
        "study": study,
        "paper": paper,
        "tolerance": tolerance.size,
        "study p": study_p,
        "paper p": str(paper_p) if paper_p is not None else "–",
        "departs in": "no data" if no_data else ", ".join(flags),
        "evidence": CALIBRATED if calibrated(family, outcome, comparison) else "",
    }


def frame(rows: list[dict[str, object]]) -> pd.DataFrame:
    """The rows as a table with the departures columns (also when there are none)."""
    return pd.DataFrame(rows, columns=list(COLUMNS))
