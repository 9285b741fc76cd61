"""Published numbers of the paper, to print beside what a simulated (or real) study reproduces.

Source: the paper in ``shared/paper/sensorless-tension-control.tex`` — Table
"torque_tension_tracking_RMSE_combined" (main text) and Supplementary Tables S1–S3 (percent-error
RMSE, peak percent errors while raising and lowering) and the kinematics table
"shoulder_kinematics_statistical_results". Values are means across 17 participants; the numbers in
brackets of the supplement are given as published (the paper calls them standard deviations).
"""

from __future__ import annotations

import pandas as pd

_SPEEDS = ("V1", "V2", "V3")
_PHASES = ("entire", "raising", "lowering")
_SUIT_CONDITIONS = ("pretension", "support_25", "support_50")


def _phase_table(rows: dict[str, tuple[float, ...]]) -> pd.DataFrame:
    """Rows condition × columns (speed, phase), as the paper lays its tracking tables out."""
    columns = pd.MultiIndex.from_product([_SPEEDS, _PHASES], names=["speed", "phase"])
    return pd.DataFrame.from_dict(rows, orient="index", columns=columns).rename_axis("condition")


def tension_rmse_n() -> pd.DataFrame:
    """Tension tracking RMSE, N (paper, main-text table)."""
    return _phase_table(
        {
            "pretension": (2.75, 2.37, 2.98, 3.58, 2.90, 3.92, 6.15, 4.51, 7.20),
            "support_25": (4.09, 3.83, 4.14, 5.31, 4.70, 5.61, 6.74, 5.70, 7.47),
            "support_50": (6.14, 6.03, 6.10, 6.46, 5.94, 6.72, 8.17, 6.80, 9.07),
        }
    )


def torque_rmse_nm() -> pd.DataFrame:
    """Shoulder torque tracking RMSE, Nm (paper, main-text table)."""
    return _phase_table(
        {
            "pretension": (0.29, 0.23, 0.32, 0.40, 0.25, 0.47, 0.69, 0.43, 0.84),
            "support_25": (0.42, 0.38, 0.44, 0.58, 0.41, 0.68, 0.74, 0.50, 0.91),
            "support_50": (0.66, 0.64, 0.66, 0.71, 0.54, 0.82, 0.90, 0.57, 1.11),
        }
    )


def percent_error_rmse() -> pd.DataFrame:
    """RMSE of the per-sample percent error, % (Supplementary Table S1; same for torque and tension)."""
    return _phase_table(
        {
            "pretension": (27.5, 23.7, 29.7, 35.8, 29.0, 39.2, 61.5, 45.1, 72.0),
            "support_25": (24.2, 22.8, 24.5, 30.5, 28.2, 31.4, 38.3, 33.6, 41.6),
            "support_50": (17.4, 17.3, 17.0, 18.2, 17.7, 18.1, 23.4, 20.6, 25.1),
        }
    )


def peak_percent_error(phase: str) -> pd.DataFrame:
    """Peak percent error and its normalised time, % (Supplementary Tables S2 raising, S3 lowering).

    Columns (speed, quantity) with quantity in ``peak_error_pct``, ``peak_error_sd``,
    ``normalised_time_pct``, ``normalised_time_sd``.
    """
    published = {
        "raising": {
            "pretension": ((-29.0, 51.5, 20.4, 18.6), (-32.3, 66.3, 10.4, 10.8), (-3.20, 112.0, 17.4, 16.4)),
            "support_25": ((-32.3, 44.3, 17.2, 16.6), (-32.1, 64.5, 10.6, 10.7), (-37.5, 70.1, 12.0, 11.3)),
            "support_50": ((-30.0, 24.8, 18.2, 17.3), (-39.4, 16.9, 7.80, 8.63), (-43.7, 23.9, 8.27, 8.69)),
        },
        "lowering": {
            "pretension": ((76.8, 54.1, 68.4, 14.2), (94.4, 71.0, 60.5, 7.76), (155.0, 90.3, 61.2, 5.48)),
            "support_25": ((58.0, 53.0, 74.0, 17.5), (80.0, 63.0, 61.4, 8.55), (99.2, 56.5, 62.3, 6.06)),
            "support_50": ((34.7, 29.9, 74.1, 17.3), (48.8, 25.3, 63.6, 8.95), (62.6, 29.2, 63.6, 6.75)),
        },
    }
    if phase not in published:
        raise ValueError(f"phase must be 'raising' or 'lowering', got {phase!r}")
    quantities = ("peak_error_pct", "peak_error_sd", "normalised_time_pct", "normalised_time_sd")
    columns = pd.MultiIndex.from_product([_SPEEDS, quantities], names=["speed", "quantity"])
    rows = {cond: sum(values, ()) for cond, values in published[phase].items()}
    return pd.DataFrame.from_dict(rows, orient="index", columns=columns).rename_axis("condition")


def kinematics() -> pd.DataFrame:
    """Elevation RMSE (deg) and SPARC (sign flipped to positive, as the paper reports it).

    Tidy: outcome, speed, condition, mean, spread (the bracketed value as published).
    """
    published = {
        "elevation_rmse_deg": {
            "V1": ((4.755, 0.299), (4.389, 0.301), (4.514, 0.29), (4.874, 0.309)),
            "V2": ((8.356, 0.584), (7.769, 0.396), (8.261, 0.462), (8.345, 0.446)),
            "V3": ((12.524, 0.868), (13.586, 0.815), (13.586, 0.862), (13.888, 0.948)),
        },
        "sparc": {
            "V1": ((2.76, 0.05), (2.752, 0.041), (2.789, 0.048), (2.832, 0.055)),
            "V2": ((2.473, 0.046), (2.476, 0.044), (2.508, 0.047), (2.554, 0.053)),
            "V3": ((2.349, 0.042), (2.368, 0.041), (2.377, 0.041), (2.416, 0.046)),
        },
    }
    conditions = ("no_suit", *_SUIT_CONDITIONS)
    rows = [
        (outcome, speed, condition, mean, spread)
        for outcome, by_speed in published.items()
        for speed, values in by_speed.items()
        for condition, (mean, spread) in zip(conditions, values, strict=True)
    ]
    return pd.DataFrame(rows, columns=["outcome", "speed", "condition", "mean", "spread"])


# GLMM p-values of the kinematics table (C, V, C×V).
KINEMATICS_P_VALUES = {
    "elevation_rmse_deg": {"condition": 0.335, "speed": "< 0.001", "interaction": 0.636},
    "sparc": {"condition": 0.023, "speed": "< 0.001", "interaction": 0.997},
}
