"""Tension and torque tracking as published: Table 1 (tab:torque_tension_tracking_RMSE_combined) and
Supplementary Tables S1 (tab:tracking_pct_RMSE_combined), S2 and S3
(tab:peak_torque_percentage_errors_raising / _lowering). Means across the 17 participants; the bracketed
spreads are given as published (the paper calls them standard deviations).
"""

from __future__ import annotations

import pandas as pd

from bowden.errors import ParameterError
from bowden.study.paper_values.tracking_data import (
    PEAK_PERCENT_ERROR,
    PERCENT_ERROR_RMSE,
    TENSION_RMSE_N,
    TORQUE_RMSE_NM,
)

SPEEDS = ("V1", "V2", "V3")
PHASES = ("entire", "raising", "lowering")
SUIT_CONDITIONS = ("pretension", "support_25", "support_50")
PEAK_QUANTITIES = ("peak_error_pct", "peak_error_sd", "normalised_time_pct", "normalised_time_sd")


def _phase_table(cells: dict[tuple[str, str, str], float]) -> pd.DataFrame:
    """Rows condition × columns (speed, phase), as the paper lays its tracking tables out."""
    columns = pd.MultiIndex.from_product([SPEEDS, PHASES], names=["speed", "phase"])
    rows = {cond: [cells[(cond, s, p)] for s, p in columns] for cond in SUIT_CONDITIONS}
    return pd.DataFrame.from_dict(rows, orient="index", columns=columns).rename_axis("condition")


def tension_rmse_n() -> pd.DataFrame:
    """Tension tracking RMSE, N (Table 1, tab:torque_tension_tracking_RMSE_combined)."""
    return _phase_table(TENSION_RMSE_N)


def torque_rmse_nm() -> pd.DataFrame:
    """Shoulder torque tracking RMSE, Nm (Table 1, tab:torque_tension_tracking_RMSE_combined)."""
    return _phase_table(TORQUE_RMSE_NM)


def percent_error_rmse() -> pd.DataFrame:
    """RMSE of the per-sample percent error, % (Table S1, tab:tracking_pct_RMSE_combined; torque too)."""
    return _phase_table(PERCENT_ERROR_RMSE)


def peak_percent_error(phase: str) -> pd.DataFrame:
    """Peak percent error and its normalised time, % (Table S2 raising, Table S3 lowering).

    Columns (speed, quantity) with quantity in :data:`PEAK_QUANTITIES`.

    Raises
    ------
    ParameterError
        ``phase`` is not ``"raising"`` or ``"lowering"``.
    """
    if phase not in ("raising", "lowering"):
        raise ParameterError(f"phase must be 'raising' or 'lowering', got {phase!r}")
    columns = pd.MultiIndex.from_product([SPEEDS, PEAK_QUANTITIES], names=["speed", "quantity"])
    rows = {
        cond: [v for speed in SPEEDS for v in PEAK_PERCENT_ERROR[(phase, cond, speed)]]
        for cond in SUIT_CONDITIONS
    }
    return pd.DataFrame.from_dict(rows, orient="index", columns=columns).rename_axis("condition")
