"""Tension and torque tracking and the peak errors beside the paper's Table 1 and Tables S1-S3.

Levels are compared in size; the growth with support (50 % minus pretension) and with speed (V3 minus
V1) in direction and size; the peak percent errors in sign and size, their times in size. Every
tracking row is marked calibrated (the simulator's friction was tuned to Table 1,
:mod:`bowden.study.departures.calibration`).
"""

from __future__ import annotations

import math

import pandas as pd

from bowden import contracts as c
from bowden.analysis.outcomes import (
    PEAK_PERCENT_ERROR,
    PEAK_PERCENT_ERROR_TIME,
    PERCENT_ERROR_RMSE,
    TENSION_RMSE,
    TORQUE_RMSE,
)
from bowden.study.departures.rows import Tolerance, comparison_row, frame
from bowden.study.paper_values.tracking_data import (
    PEAK_PERCENT_ERROR as PAPER_PEAKS,
)
from bowden.study.paper_values.tracking_data import (
    PERCENT_ERROR_RMSE as PAPER_PERCENT,
)
from bowden.study.paper_values.tracking_data import (
    TENSION_RMSE_N,
    TORQUE_RMSE_NM,
)

SUIT = (c.CONDITION_PRETENSION, c.CONDITION_SUPPORT_25, c.CONDITION_SUPPORT_50)
# measure -> (name, unit, the paper's table, tolerance of a level or a difference)
MEASURES = {
    TENSION_RMSE: ("tension RMSE", "N", TENSION_RMSE_N, 1.0),
    TORQUE_RMSE: ("torque RMSE", "Nm", TORQUE_RMSE_NM, 0.1),
    PERCENT_ERROR_RMSE: ("percent-error RMSE", "%", PAPER_PERCENT, 5.0),
}
PEAK_TOLERANCE = Tolerance(size=20.0, dead_zone=5.0)  # points; the paper's SDs are 17-112 points
TIME_TOLERANCE = Tolerance(size=10.0, direction=False)  # points of the normalised cycle


def _means(outcomes: pd.DataFrame, measure: str) -> pd.Series:
    """Mean over participants of each participant's mean, by (condition, speed, phase)."""
    data = outcomes[outcomes["measure"] == measure].dropna(subset=["value"])
    if data.empty:
        return pd.Series(dtype=float)
    per_participant = data.groupby(["condition", "speed", "phase", "participant"])["value"].mean()
    return per_participant.groupby(["condition", "speed", "phase"]).mean()


def _get(means: pd.Series, *key: str) -> float:
    value = means.get(key)
    return float(value) if value is not None else math.nan


def tracking_departures(outcomes: pd.DataFrame) -> pd.DataFrame:
    """Rows for Table 1, S1 (levels and trends, entire cycle) and S2-S3 (peaks)."""
    rows = []
    for measure, (name, unit, paper, size) in MEASURES.items():
        means = _means(outcomes, measure)
        level, trend = Tolerance(size, direction=False), Tolerance(size, dead_zone=0.1 * size)
        for condition in SUIT:
            for speed in c.SPEEDS:
                rows.append(comparison_row(
                    family="tracking", outcome=f"{name}, level", unit=unit,
                    comparison=f"{c.CONDITION_LABELS[condition]} {speed}",
                    study=_get(means, condition, speed, "entire"),
                    paper=paper[(condition, speed, "entire")], tolerance=level,
                ))
        for speed in c.SPEEDS:
            high, low = c.CONDITION_SUPPORT_50, c.CONDITION_PRETENSION
            rows.append(comparison_row(
                family="tracking", outcome=f"{name}, growth with support", unit=unit,
                comparison=f"50%-pre {speed}",
                study=_get(means, high, speed, "entire") - _get(means, low, speed, "entire"),
                paper=paper[(high, speed, "entire")] - paper[(low, speed, "entire")], tolerance=trend,
            ))
        for condition in SUIT:
            rows.append(comparison_row(
                family="tracking", outcome=f"{name}, growth with speed", unit=unit,
                comparison=f"V3-V1 {c.CONDITION_LABELS[condition]}",
                study=_get(means, condition, "V3", "entire") - _get(means, condition, "V1", "entire"),
                paper=paper[(condition, "V3", "entire")] - paper[(condition, "V1", "entire")],
                tolerance=trend,
            ))
    peaks = {PEAK_PERCENT_ERROR: _means(outcomes, PEAK_PERCENT_ERROR),
             PEAK_PERCENT_ERROR_TIME: _means(outcomes, PEAK_PERCENT_ERROR_TIME)}
    for phase, table in (("raising", "S2"), ("lowering", "S3")):
        for condition in SUIT:
            for speed in c.SPEEDS:
                peak, _, time, _ = PAPER_PEAKS[(phase, condition, speed)]
                where = f"{c.CONDITION_LABELS[condition]} {speed}"
                rows.append(comparison_row(
                    family="peak errors", outcome=f"peak error, {phase} ({table})", unit="%",
                    comparison=where, study=_get(peaks[PEAK_PERCENT_ERROR], condition, speed, phase),
                    paper=peak, tolerance=PEAK_TOLERANCE,
                ))
                rows.append(comparison_row(
                    family="peak errors", outcome=f"time of peak, {phase} ({table})", unit="% of cycle",
                    comparison=where, study=_get(peaks[PEAK_PERCENT_ERROR_TIME], condition, speed, phase),
                    paper=time, tolerance=TIME_TOLERANCE,
                ))
    return frame(rows)
