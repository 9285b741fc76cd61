"""Normalised iEMG as published: mean (SD) and GLMM p-values (Supplementary Tables S7-S9:
tab:iEMG_whole_mean, tab:iEMG_raise_mean, tab:iEMG_lower_mean), the pairwise comparisons (S10-S12:
tab:pairwise_whole, tab:pairwise_raising, tab:pairwise_lowering) and the colour tables (Table 2
tab:iEMG_deltas_visual_raising, Table 3 tab:iEMG_deltas_visual_lowering, and the supplement's
tab:iEMG_deltas_visual for the entire cycle).
"""

from __future__ import annotations

import pandas as pd

from bowden.errors import ParameterError
from bowden.study.paper_values.iemg_data import IEMG, IEMG_COLOURS, IEMG_P, IEMG_PAIRS
from bowden.study.paper_values.pvalue import P

PHASES = ("entire", "raising", "lowering")
TABLE_LABELS = {
    "means": {"entire": "S7", "raising": "S8", "lowering": "S9"},
    "pairs": {"entire": "S10", "raising": "S11", "lowering": "S12"},
    "colours": {"entire": "tab:iEMG_deltas_visual", "raising": "Table 2", "lowering": "Table 3"},
}


def _check(phase: str) -> None:
    if phase not in PHASES:
        raise ParameterError(f"phase must be one of {PHASES}, got {phase!r}")


def iemg_means(phase: str) -> pd.DataFrame:
    """Tidy mean and SD per muscle, speed and condition (Tables S7-S9)."""
    _check(phase)
    rows = [(m, s, c, mean, sd) for (ph, m, s, c), (mean, sd) in IEMG.items() if ph == phase]
    return pd.DataFrame(rows, columns=["muscle", "speed", "condition", "mean", "sd"])


def iemg_p(phase: str, muscle: str) -> dict[str, P]:
    """GLMM p-values of condition, speed and interaction for one muscle (Tables S7-S9)."""
    _check(phase)
    try:
        values = IEMG_P[(phase, muscle)]
    except KeyError:
        raise ParameterError(f"the paper reports no muscle {muscle!r}") from None
    return dict(zip(("condition", "speed", "interaction"), values, strict=True))


def iemg_pairs(phase: str) -> pd.DataFrame:
    """Change first − second, percent change and p of each pair of conditions (Tables S10-S12)."""
    _check(phase)
    rows = [(m, a, b, ch, pct, p) for (ph, m, a, b), (ch, pct, p) in IEMG_PAIRS.items() if ph == phase]
    return pd.DataFrame(rows, columns=["muscle", "first", "second", "change", "percent", "p"])


def iemg_colours(phase: str) -> pd.DataFrame:
    """Cell colour (RGB) and printed significance code of the colour tables (Tables 2, 3, S-visual)."""
    _check(phase)
    rows = [(m, a, b, rgb, code) for (ph, m, a, b), (rgb, code) in IEMG_COLOURS.items() if ph == phase]
    return pd.DataFrame(rows, columns=["muscle", "first", "second", "rgb", "code"])
