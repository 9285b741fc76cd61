"""The paper's tables in the shapes of the report's own, so that each can stand beside the study's.

:func:`paper_effects_table` mirrors :func:`bowden.stats.effects_table` (Tables S4, S7-S9),
:func:`paper_pairwise_table` mirrors :func:`bowden.stats.pairwise_table` (Tables S5, S6, S10-S12) and
:func:`paper_means` gives the per-condition and speed means the box plots mark (S4, S7) and
:func:`paper_significance_html` draws the paper's iEMG colour tables (Tables 2, 3) as the report
draws its own.
"""

from __future__ import annotations

import pandas as pd

from bowden.analysis.outcomes import ELEVATION_RMSE, IEMG_PREFIX, SPARC
from bowden.contracts import CONDITION_LABELS, CONDITIONS, SPEEDS
from bowden.stats.tables import coloured_cells_html
from bowden.study.paper_values.iemg import iemg_colours
from bowden.study.paper_values.iemg_data import IEMG, IEMG_P, IEMG_PAIRS
from bowden.study.paper_values.kinematics_data import (
    KINEMATICS,
    KINEMATICS_CONDITION_PAIRS,
    KINEMATICS_P,
    KINEMATICS_SPEED_PAIRS,
)
from bowden.study.statistics import KINEMATIC_LABELS, MUSCLE_LABELS

P_COLUMNS = ("p (C)", "p (V)", "p (C x V)")
_KINEMATIC_KEYS = {ELEVATION_RMSE: "elevation_rmse_deg", SPARC: "sparc"}


def _label(level: str) -> str:
    return CONDITION_LABELS.get(level, level)


def paper_effects_table(phase: str | None) -> pd.DataFrame:
    """Mean (SD) per condition and speed with the GLMM p-values: S4 (``phase`` None) or S7-S9."""
    if phase is None:
        outcomes = {KINEMATIC_LABELS[m]: key for m, key in _KINEMATIC_KEYS.items()}
        means = {(label, s, c): KINEMATICS[(key, s, c)] for label, key in outcomes.items()
                 for s in SPEEDS for c in CONDITIONS}
        pvalues = {label: KINEMATICS_P[key] for label, key in outcomes.items()}
    else:
        means = {(MUSCLE_LABELS[m], s, c): v for (ph, m, s, c), v in IEMG.items() if ph == phase}
        pvalues = {MUSCLE_LABELS[m]: p for (ph, m), p in IEMG_P.items() if ph == phase}
    rows = []
    for outcome, p in pvalues.items():
        for speed in SPEEDS:
            row: dict[str, str] = {"outcome": outcome, "speed": speed}
            for condition in CONDITIONS:
                mean, sd = means[(outcome, speed, condition)]
                row[_label(condition)] = f"{mean:.3f} ({sd:.3f})"
            row.update({column: str(value) for column, value in zip(P_COLUMNS, p, strict=True)})
            rows.append(row)
    return pd.DataFrame(rows).set_index(["outcome", "speed"])


def paper_pairwise_table(factor: str, phase: str | None) -> pd.DataFrame:
    """Change, percent and p per comparison: S5 (conditions) / S6 (speeds) for ``phase`` None, else S10-S12.

    Kinematic changes carry their SE in brackets and no percent (the paper gives none); the paper did
    not compare conditions for elevation RMSE (no condition effect), so that row is absent.
    """
    cells: dict[str, dict[tuple[str, str], str]] = {}
    if phase is None:
        source = KINEMATICS_CONDITION_PAIRS if factor == "condition" else KINEMATICS_SPEED_PAIRS
        labels = {key: KINEMATIC_LABELS[m] for m, key in _KINEMATIC_KEYS.items()}
        for (key, a, b), (change, se, p) in source.items():
            contrast = f"{_label(a)}-{_label(b)}"
            cells.setdefault(labels[key], {}).update(
                {(contrast, "change"): f"{change:.3f} ({se:.3f})", (contrast, "percent"): "–",
                 (contrast, "p"): str(p)}
            )
    else:
        for (ph, muscle, a, b), (change, percent, p) in IEMG_PAIRS.items():
            if ph != phase:
                continue
            contrast = f"{_label(a)}-{_label(b)}"
            cells.setdefault(MUSCLE_LABELS[muscle], {}).update(
                {(contrast, "change"): f"{change:.3f}", (contrast, "percent"): f"{percent:.1f}",
                 (contrast, "p"): str(p)}
            )
    table = pd.DataFrame.from_dict(cells, orient="index")
    table.columns = pd.MultiIndex.from_tuples([tuple(col) for col in table.columns])
    table.index.name = "outcome"
    return table


def paper_means(measure: str) -> dict[tuple[str, str], float]:
    """(condition, speed) -> the paper's mean: S4 for elevation RMSE/SPARC, S7 for an iEMG measure."""
    if measure in _KINEMATIC_KEYS:
        key = _KINEMATIC_KEYS[measure]
        return {(c, s): mean for (k, s, c), (mean, _) in KINEMATICS.items() if k == key}
    muscle = measure.removeprefix(IEMG_PREFIX)
    return {(c, s): mean for (ph, m, s, c), (mean, _) in IEMG.items() if ph == "entire" and m == muscle}


def paper_significance_html(phase: str, caption: str) -> str:
    """The paper's colour table of iEMG changes between conditions (Tables 2 and 3, and the
    supplement's for the entire cycle) as the report draws its own: each cell in the paper's colour
    with its printed significance code, and on hover its percent change and p (Tables S10-S12)."""
    frame = iemg_colours(phase)
    muscles = [MUSCLE_LABELS[m] for m in dict.fromkeys(frame["muscle"])]
    cells: dict[tuple[str, str], tuple[str, str, str]] = {}
    contrasts: dict[str, None] = {}
    for muscle, first, second, rgb, code in frame.itertuples(index=False, name=None):
        contrast = f"{_label(first)}-{_label(second)}"
        contrasts[contrast] = None
        pair = IEMG_PAIRS.get((phase, muscle, first, second))
        title = f"{pair[1]:+.1f} %, p = {pair[2]}" if pair is not None else ""
        cells[(MUSCLE_LABELS[muscle], contrast)] = ("rgb({}, {}, {})".format(*rgb), code, title)
    return coloured_cells_html(muscles, list(contrasts), cells, caption=caption, index_name="outcome")
