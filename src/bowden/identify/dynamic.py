"""Identify the dynamic compensation (:mod:`bowden.model.dynamic`) from the paper's bench recording.

Two steps on the same filtered recording the paper's lines come from:

1. **Friction and drag** from the steady-state samples of every speed: one robust regression (Tukey's
   bisquare, statsmodels' RLM) of motor torque on the two lines — intercept and slope per direction —
   and a drag term common to both, b·ω. Where the paper fits a line per direction over all speeds, the
   drag moves each line's intercept with speed ("lines fanning out"); here it gets its own term, so the
   intercepts are the Coulomb friction alone.
2. **Inertia** from the whole time series: the residual of step 1 on the ramps (where the spool
   accelerates and decelerates between strokes, excluded from the steady state) regressed on the spool
   acceleration, through the origin, robustly.

The IMU's latency, which the controller's estimator predicts across, is not a property of the
transmission and the paper's bench strokes (constant speed, one stroke per segment) do not show it
reliably: it is a setting (``imu_latency_s``, default :data:`DEFAULT_IMU_LATENCY_S`).

Fit quality is reported per regime (steady raising, steady lowering, ramps, turns) against the
paper's lines on the same samples, so a lab sees what each term buys on its own suit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from statsmodels.robust.norms import TukeyBiweight
from statsmodels.robust.robust_linear_model import RLM, RLMResults

from bowden.errors import FitError
from bowden.identify.preprocess import SteadyStateSelection
from bowden.identify.settings import DEFAULT_IMU_LATENCY_S as DEFAULT_IMU_LATENCY_S  # re-exported
from bowden.model.compensation import CompensationModel
from bowden.model.dynamic import DynamicCompensation, DynamicFitStats
from bowden.model.lines import CompensationLine

# Ramps: accelerating or braking harder than this (the steady-state limit is 15 °/s²) while moving.
MIN_RAMP_ACCELERATION_RAD_S2 = 2.0
MIN_RAMP_SAMPLES = 50


@dataclass(frozen=True, eq=False)
class DynamicIdentification:
    """The identified dynamic compensation and what it was identified from."""

    dynamic: DynamicCompensation
    viscous_fit: RLMResults


def identify_dynamic(
    selection: SteadyStateSelection, paper: CompensationModel, *, imu_latency_s: float = DEFAULT_IMU_LATENCY_S
) -> DynamicIdentification:
    """Identify the dynamic compensation from a steady-state selection (which holds the filtered data).

    Raises
    ------
    FitError
        When the regression is degenerate (one speed only: drag and Coulomb friction cannot be told
        apart) or gives parameters no transmission has (negative drag, raising below lowering).
    """
    filtered = selection.filtered
    velocity = filtered.motor_velocity_rad_s
    speeds = np.abs(velocity[selection.selected])
    if speeds.size == 0 or np.ptp(speeds) < 0.25 * float(np.median(speeds)):
        raise FitError(
            "the dynamic model needs steady-state samples at several spool speeds (the paper's protocol "
            "runs 0.5–6 rad/s) to tell drag from Coulomb friction; this recording has one speed"
        )
    design, torque = _steady_design(selection)
    fit = RLM(torque, design, M=TukeyBiweight()).fit()
    low_i, low_s, up_i, up_s, viscous = (float(v) for v in fit.params)
    viscous_se = float(fit.bse[4])
    if viscous < 0.0:
        raise FitError(
            f"the drag identified is negative ({viscous:.4g} Nm·s/rad): motor torque falls with spool speed "
            "in this recording, which friction cannot explain; check the sign of motor_velocity_rad_s"
        )
    if not (0.0 < low_s <= up_s < 1.0):
        raise FitError(
            f"the dynamic model's slopes (raising {up_s:.4g} m, lowering {low_s:.4g} m) are not a "
            "transmission's: raising must need at least the lowering torque per newton"
        )
    raising = CompensationLine(intercept_nm=up_i, slope_m=up_s)
    lowering = CompensationLine(intercept_nm=low_i, slope_m=low_s)
    inertia, inertia_se, ramps = _inertia(selection, raising, lowering, viscous)
    unfitted = DynamicCompensation(
        raising=raising,
        lowering=lowering,
        viscous_nm_s_rad=viscous,
        inertia_kg_m2=inertia,
        imu_latency_s=imu_latency_s,
    )
    regimes = _regimes(selection, ramps)
    dynamic_rms = {name: _rms_dynamic(selection, mask, unfitted) for name, mask in regimes.items()}
    paper_rms = {name: _rms_paper(selection, mask, paper) for name, mask in regimes.items()}
    stats = DynamicFitStats(
        n=int(torque.size),
        viscous_se_nm_s_rad=viscous_se,
        inertia_se_kg_m2=inertia_se,
        regime_rms_nm=tuple((k, v) for k, v in dynamic_rms.items() if math.isfinite(v)),
        paper_rms_nm=tuple((k, v) for k, v in paper_rms.items() if math.isfinite(v)),
    )
    return DynamicIdentification(dynamic=replace(unfitted, fit=stats), viscous_fit=fit)


def _steady_design(selection: SteadyStateSelection) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Columns: lowering intercept, lowering slope, raising intercept, raising slope, drag."""
    f = selection.filtered
    mask = selection.raising | selection.lowering
    tension = f.tension_n[mask]
    velocity = f.motor_velocity_rad_s[mask]
    up = selection.raising[mask].astype(np.float64)
    down = 1.0 - up
    design = np.column_stack([down, down * tension, up, up * tension, velocity])
    return design, f.motor_torque_nm[mask]


def _coulomb(
    raising: CompensationLine,
    lowering: CompensationLine,
    tension: NDArray[np.float64],
    direction: NDArray[np.float64],
) -> NDArray[np.float64]:
    up = raising.intercept_nm + raising.slope_m * tension
    down = lowering.intercept_nm + lowering.slope_m * tension
    return down + (up - down) * 0.5 * (direction + 1.0)


def _ramp_mask(selection: SteadyStateSelection) -> NDArray[np.bool_]:
    f = selection.filtered
    settings = selection.settings
    with np.errstate(invalid="ignore"):
        return (
            (f.segment >= 0)
            & (np.abs(f.motor_velocity_rad_s) > settings.min_speed_rad_s)
            & (np.abs(f.motor_acceleration_rad_s2) > MIN_RAMP_ACCELERATION_RAD_S2)
            & selection.criteria["elevation"]
            & selection.criteria["torque"]
        )


def _inertia(
    selection: SteadyStateSelection, raising: CompensationLine, lowering: CompensationLine, viscous: float
) -> tuple[float, float, NDArray[np.bool_]]:
    """Rotor inertia from the ramps' residual torque against spool acceleration (0 with too few ramps)."""
    f = selection.filtered
    ramps = _ramp_mask(selection)
    if np.count_nonzero(ramps) < MIN_RAMP_SAMPLES:
        return 0.0, 0.0, ramps
    velocity = f.motor_velocity_rad_s[ramps]
    direction = np.sign(velocity)
    residual = f.motor_torque_nm[ramps] - _coulomb(raising, lowering, f.tension_n[ramps], direction)
    residual -= viscous * velocity
    acceleration = f.motor_acceleration_rad_s2[ramps][:, None]
    fit = RLM(residual, acceleration, M=TukeyBiweight()).fit()
    inertia = float(fit.params[0])
    # A negative or absurd inertia is noise on too gentle ramps: the term is then left out.
    if not 0.0 <= inertia <= 0.05:
        return 0.0, float(fit.bse[0]), ramps
    return inertia, float(fit.bse[0]), ramps


def _regimes(selection: SteadyStateSelection, ramps: NDArray[np.bool_]) -> dict[str, NDArray[np.bool_]]:
    f = selection.filtered
    settings = selection.settings
    with np.errstate(invalid="ignore"):
        turning = (
            (f.segment >= 0)
            & (np.abs(f.motor_velocity_rad_s) <= settings.min_speed_rad_s)
            & selection.criteria["elevation"]
            & selection.criteria["torque"]
        )
    return {
        "steady raising": selection.raising,
        "steady lowering": selection.lowering,
        "ramps": ramps,
        "turns": turning,
    }


def _rms(values: NDArray[np.float64]) -> float:
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values * values))) if values.size else math.nan


def _rms_dynamic(
    selection: SteadyStateSelection, mask: NDArray[np.bool_], model: DynamicCompensation
) -> float:
    f = selection.filtered
    velocity = f.motor_velocity_rad_s[mask]
    predicted = _coulomb(model.raising, model.lowering, f.tension_n[mask], np.sign(velocity))
    predicted += np.clip(
        model.viscous_nm_s_rad * velocity + model.inertia_kg_m2 * f.motor_acceleration_rad_s2[mask],
        -model.max_dynamic_nm,
        model.max_dynamic_nm,
    )
    return _rms(f.motor_torque_nm[mask] - predicted)


def _rms_paper(selection: SteadyStateSelection, mask: NDArray[np.bool_], model: CompensationModel) -> float:
    """The paper's lines, each on its own direction of spool travel (as they were fitted)."""
    f = selection.filtered
    direction = np.sign(f.motor_velocity_rad_s[mask])
    predicted = _coulomb(model.raising, model.lowering, f.tension_n[mask], direction)
    return _rms(f.motor_torque_nm[mask] - predicted)


def format_dynamic(dynamic: DynamicCompensation) -> str:
    """The dynamic model as ``bowden identify`` prints it: parameters, uncertainties, fit per regime."""
    fit = dynamic.fit
    drag = f"{1e3 * dynamic.viscous_nm_s_rad:.2f} mNm·s/rad"
    inertia = f"{1e3 * dynamic.inertia_kg_m2:.3f} g·m²"
    if fit is not None:
        drag += f" ± {1e3 * fit.viscous_se_nm_s_rad:.2f}"
        inertia += f" ± {1e3 * fit.inertia_se_kg_m2:.3f}"
    up, down = dynamic.raising, dynamic.lowering
    if dynamic.recommended_cells and not dynamic.recommended:
        cells = [f"{support} {speed}" for support, speed, chosen in dynamic.recommended_cells if chosen]
        choice = (f"recommended where the bench showed it winning ({', '.join(cells) or 'no cell'}; "
                  f"{dynamic.recommendation}); the paper's lines elsewhere")
    elif dynamic.recommended:
        choice = f"recommended ({dynamic.recommendation}); compensation='paper' forces the paper's lines"
    else:
        choice = (f"NOT recommended ({dynamic.recommendation}); the controller uses the paper's lines "
                  "unless asked for compensation='dynamic'")
    lines = [
        f"Dynamic compensation, {choice}:",
        f"  Coulomb lines: raising {up.intercept_nm:+.4f} Nm + {1e3 * up.slope_m:.3f} mm·T,"
        f" lowering {down.intercept_nm:+.4f} Nm + {1e3 * down.slope_m:.3f} mm·T",
        f"  drag {drag}, inertia {inertia}, IMU latency {1e3 * dynamic.imu_latency_s:.1f} ms",
    ]
    if fit is not None and fit.regime_rms_nm:
        paper = dict(fit.paper_rms_nm)
        lines.append("  torque residual RMS per regime (dynamic / paper's lines):")
        for name, value in fit.regime_rms_nm:
            lines.append(
                f"    {name:16s} {1e3 * value:7.1f} / {1e3 * paper.get(name, float('nan')):7.1f} mNm"
            )
    return "\n".join(lines)
