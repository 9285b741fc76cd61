"""One way to print a p-value in every table of the report: ``"< 0.001"`` below 0.001, else three decimals.

The statistics return p-values as floats that can underflow to 0 or read 1.4e-186; a reviewer
comparing them with the paper's "< 0.001" should see the same form everywhere. The paper's own
values are kept as it printed them (strings such as ``"0.05"`` or ``"< 0.001"``): a reformatted
"0.050" would claim a digit the paper did not print.
"""

from __future__ import annotations

import math
import re
from typing import Any

import pandas as pd

from bowden.stats.tables import format_p

# Column labels that hold p-values: "p", "p (C)", "study p", "paper p", "p_holm", "p-value".
_P_LABEL = re.compile(r"^((study|paper) )?p(-value)?( \(.+\))?$|^p_[a-z]+$", re.IGNORECASE)


def is_p_label(label: Any) -> bool:
    """Whether a column label (the last level of a MultiIndex column) names a p-value."""
    last = label[-1] if isinstance(label, tuple) else label
    return isinstance(last, str) and _P_LABEL.match(last.strip()) is not None


def p_text(value: Any) -> Any:
    """A computed p-value (a float) in the report's form; anything else (a printed value, "–") as is."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return value
    p = float(value)
    return "–" if math.isnan(p) else format_p(p)


def format_p_columns(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with every p-value column's numbers printed by :func:`p_text` (a copy if any is)."""
    columns = [column for column in frame.columns if is_p_label(column)]
    if not columns:
        return frame
    frame = frame.copy()
    for column in columns:
        frame[column] = frame[column].astype(object).map(p_text)
    return frame
