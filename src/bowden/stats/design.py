"""The two-factor repeated-measures design: input checks, level order and the fixed-effects matrix.

The fixed effects are condition, speed and their interaction in sum-to-zero ("effect") coding, the
coding under which the Type-III hypotheses of SPSS and SAS are plain "these coefficients are zero"
(R: ``options(contrasts = c("contr.sum", "contr.poly"))``). Columns come in R's ``model.matrix`` order
so coefficients line up one to one with R's output.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pandas as pd

from bowden.contracts import CONDITIONS, SPEEDS
from bowden.errors import OutcomeTableError

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]

TERMS = ("condition", "speed", "condition:speed")


@dataclass(frozen=True, kw_only=True)
class Design:
    """A validated outcome table turned into model matrices.

    Attributes
    ----------
    y:
        Outcome, shape (n,), all > 0.
    x:
        Fixed-effects matrix, shape (n, p), sum-to-zero coding, R's column order.
    group:
        Participant index per row, shape (n,), values 0..m-1.
    participants:
        Participant ids in index order.
    conditions, speeds:
        Level names in model order.
    coef_names:
        Names of the p columns of ``x``.
    term_columns:
        Column indices of each term (``"condition"``, ``"speed"``, ``"condition:speed"``).
    condition_index, speed_index:
        Level index per row.
    """

    y: FloatArray
    x: FloatArray
    group: IntArray
    participants: tuple[str, ...]
    conditions: tuple[str, ...]
    speeds: tuple[str, ...]
    coef_names: tuple[str, ...]
    term_columns: dict[str, IntArray]
    condition_index: IntArray
    speed_index: IntArray

    @property
    def n_obs(self) -> int:
        return int(self.y.size)

    @property
    def n_participants(self) -> int:
        return len(self.participants)

    def cell_row(self, condition: int, speed: int) -> FloatArray:
        """Design row of one condition x speed cell (the reference grid of the marginal means)."""
        return model_row(condition, speed, len(self.conditions), len(self.speeds))


def _sum_code(index: int, n_levels: int) -> FloatArray:
    row = np.zeros(n_levels - 1)
    if index < n_levels - 1:
        row[index] = 1.0
    else:
        row[:] = -1.0
    return row


def model_row(condition: int, speed: int, n_conditions: int, n_speeds: int) -> FloatArray:
    """One row of the fixed-effects matrix for level indices ``condition`` and ``speed``."""
    c = _sum_code(condition, n_conditions)
    v = _sum_code(speed, n_speeds)
    # R orders interaction columns with the first factor varying fastest.
    return np.concatenate(([1.0], c, v, np.outer(v, c).ravel()))


def order_levels(values: pd.Series, preferred: Sequence[str]) -> tuple[str, ...]:
    """Level order: a categorical's own order, else ``preferred`` if it covers them, else first seen."""
    if isinstance(values.dtype, pd.CategoricalDtype):
        present = set(values.dropna().astype(str))
        return tuple(str(c) for c in values.cat.categories if str(c) in present)
    seen = tuple(dict.fromkeys(values.astype(str)))
    if set(seen) <= set(preferred):
        return tuple(level for level in preferred if level in set(seen))
    return seen


def build_design(
    data: pd.DataFrame,
    *,
    participant: str = "participant",
    condition: str = "condition",
    speed: str = "speed",
    value: str = "value",
) -> Design:
    """Check a tidy outcome table and build the model matrices.

    Parameters
    ----------
    data:
        One row per observation (repetition), with the four named columns.
    participant, condition, speed, value:
        Column names.

    Raises
    ------
    OutcomeTableError
        A column is missing, a value is missing, not finite or not > 0 (the gamma family needs
        positive outcomes), a condition x speed cell is empty, or fewer than two participants or
        levels are present.
    """
    y = _checked_outcomes(data, (participant, condition, speed), value)
    conditions = order_levels(data[condition], CONDITIONS)
    speeds = order_levels(data[speed], SPEEDS)
    participants = tuple(dict.fromkeys(data[participant].astype(str)))
    for name, levels in ((condition, conditions), (speed, speeds), (participant, participants)):
        if len(levels) < 2:
            raise OutcomeTableError(f"column {name!r} needs at least two levels, found {list(levels)}")
    c_idx = _codes(data[condition], conditions)
    v_idx = _codes(data[speed], speeds)
    g_idx = _codes(data[participant], participants)
    counts = np.zeros((len(conditions), len(speeds)), dtype=int)
    np.add.at(counts, (c_idx, v_idx), 1)
    empty = np.argwhere(counts == 0)
    if empty.size:
        cells = ", ".join(f"{conditions[c]} x {speeds[v]}" for c, v in empty)
        raise OutcomeTableError(f"empty condition x speed cell(s): {cells}")
    n_c, n_v = len(conditions), len(speeds)
    grid = np.array([[model_row(c, v, n_c, n_v) for v in range(n_v)] for c in range(n_c)])
    x = grid[c_idx, v_idx]
    names = ["(Intercept)"]
    names += [f"{condition}[{lvl}]" for lvl in conditions[:-1]]
    names += [f"{speed}[{lvl}]" for lvl in speeds[:-1]]
    names += [f"{condition}[{c}]:{speed}[{v}]" for v in speeds[:-1] for c in conditions[:-1]]
    start_v = n_c
    start_i = n_c + n_v - 1
    term_columns = {
        "condition": np.arange(1, n_c, dtype=np.intp),
        "speed": np.arange(start_v, start_i, dtype=np.intp),
        "condition:speed": np.arange(start_i, x.shape[1], dtype=np.intp),
    }
    if np.linalg.matrix_rank(x) < x.shape[1]:
        raise OutcomeTableError("the fixed-effects matrix is rank deficient")
    return Design(
        y=y,
        x=x,
        group=g_idx,
        participants=participants,
        conditions=conditions,
        speeds=speeds,
        coef_names=tuple(names),
        term_columns=term_columns,
        condition_index=c_idx,
        speed_index=v_idx,
    )


def _checked_outcomes(data: pd.DataFrame, factors: tuple[str, str, str], value: str) -> FloatArray:
    """The ``value`` column as floats, after checking that every column is there and filled and every
    value is finite and > 0 (the gamma family's support)."""
    if not isinstance(data, pd.DataFrame):
        raise OutcomeTableError(f"expected a pandas DataFrame, got {type(data).__name__}")
    for col in (*factors, value):
        if col not in data.columns:
            raise OutcomeTableError(f"column {col!r} is missing (columns: {list(data.columns)})")
    for col in factors:
        missing = data[col].isna().to_numpy()
        if missing.any():
            raise OutcomeTableError(f"column {col!r} is empty in row {data.index[int(np.argmax(missing))]!r}")
    y = pd.to_numeric(data[value], errors="coerce").to_numpy(dtype=float)
    bad = ~(np.isfinite(y) & (y > 0.0))
    if bad.any():
        row = int(np.argmax(bad))
        raise OutcomeTableError(
            f"column {value!r} must be finite and > 0 for a gamma model; row {data.index[row]!r} "
            f"holds {data[value].iloc[row]!r}"
        )
    return y


def _codes(values: pd.Series, levels: Sequence[str]) -> IntArray:
    lookup = {lvl: k for k, lvl in enumerate(levels)}
    as_text = values.astype(str).to_numpy()
    unknown = [v for v in dict.fromkeys(as_text) if v not in lookup]
    if unknown:
        raise OutcomeTableError(f"levels {unknown} are not in the level order {list(levels)}")
    return np.fromiter((lookup[v] for v in as_text), dtype=np.intp, count=as_text.size)
