"""What an identification found, in words: lines, fit quality, implied friction, warnings.

The single-bend law (paper, supplement §1) predicts motor-torque slopes
m_raise = R(1+k)/(1−k) and m_lower = R(1−k)/(1+k) for a pulley radius R and friction factor
k = μ·sin(φ/2). Two consequences are checked:

* the slope ratio gives k back, m_raise/m_lower = ((1+k)/(1−k))², whatever R
  (:func:`bowden.model.transmission.friction_from_slopes`);
* the geometric mean sqrt(m_raise·m_lower) equals R: friction cancels and intercepts play no part.
  When it differs from the pulley radius, one k cannot explain both slopes (a torque-constant error
  scales both; losses that do not scale with tension, several bends with different behaviour, or a
  wrong pulley radius also show up here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bowden.errors import ParameterError
from bowden.identify.robustfit import RobustFit
from bowden.identify.settings import LOWERING, RAISING
from bowden.model.transmission import friction_from_slopes


@dataclass(frozen=True, kw_only=True)
class SummaryThresholds:
    """When the summary warns.

    Parameters
    ----------
    min_samples
        Warn when a direction has fewer steady-state samples than this.
    min_r_squared
        Warn when either R² of a direction is below this (the paper reached 0.9940 and 0.9906).
    radius_tolerance
        Relative difference between sqrt(m_raise·m_lower) and the pulley radius still accepted as
        "consistent with one k".
    max_rejected_fraction
        Warn when the bisquare weights reject (w = 0) more than this fraction of a direction.
    """

    min_samples: int = 500
    min_r_squared: float = 0.98
    radius_tolerance: float = 0.05
    max_rejected_fraction: float = 0.10

    def __post_init__(self) -> None:
        if (
            isinstance(self.min_samples, bool)
            or not isinstance(self.min_samples, int)
            or self.min_samples < 3
        ):
            raise ParameterError(f"min_samples must be an integer >= 3, got {self.min_samples!r}")
        for name in ("min_r_squared", "radius_tolerance", "max_rejected_fraction"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and 0.0 <= value <= 1.0):
                raise ParameterError(f"{name} must be in [0, 1], got {value!r}")


@dataclass(frozen=True, kw_only=True)
class DirectionSummary:
    """One identified line: torque_nm = intercept_nm + slope_m · tension_n."""

    direction: str
    n: int
    intercept_nm: float
    slope_m: float
    intercept_se_nm: float
    slope_se_m: float
    r_squared_ols: float
    r_squared_fitlm_robust: float
    robust_scale_nm: float
    rejected_fraction: float
    converged: bool

    @classmethod
    def from_fit(cls, direction: str, fit: RobustFit) -> DirectionSummary:
        return cls(
            direction=direction,
            n=fit.n,
            intercept_nm=fit.intercept,
            slope_m=fit.slope,
            intercept_se_nm=fit.intercept_se,
            slope_se_m=fit.slope_se,
            r_squared_ols=fit.r_squared_ols,
            r_squared_fitlm_robust=fit.r_squared_fitlm_robust,
            robust_scale_nm=fit.scale,
            rejected_fraction=float((fit.weights == 0.0).mean()),
            converged=fit.converged,
        )


@dataclass(frozen=True, kw_only=True)
class IdentificationSummary:
    """Both lines, the friction they imply, and what looks wrong.

    Attributes
    ----------
    k
        μ·sin(φ/2) from the slope ratio, or None when the raising slope is not the larger one.
    geometric_mean_slope_m
        sqrt(m_raise·m_lower), m: equals the pulley radius under the single-bend law.
    radius_deviation
        geometric_mean_slope_m / pulley_radius_m − 1.
    consistent_with_one_k
        |radius_deviation| within the tolerance.
    """

    raising: DirectionSummary
    lowering: DirectionSummary
    pulley_radius_m: float
    k: float | None
    geometric_mean_slope_m: float
    radius_deviation: float
    consistent_with_one_k: bool
    warnings: tuple[str, ...]

    def format(self) -> str:
        """A plain-text report for the terminal (each R² labelled by its definition: fitlm robust, OLS)."""
        lines = ["Identified compensation lines (motor torque = intercept + slope · tension):"]
        header = (
            f"  {'direction':<10}{'n':>8}  {'intercept [Nm]':>20}  {'slope [mm]':>18}"
            f"  {'R² fitlm-robust':>15}  {'R² OLS':>8}  {'scale [Nm]':>10}"
        )
        lines.append(header)
        for line in (self.raising, self.lowering):
            lines.append(
                f"  {line.direction:<10}{line.n:>8}  "
                f"{line.intercept_nm:>+10.4f} ± {line.intercept_se_nm:<7.4f}  "
                f"{1e3 * line.slope_m:>8.3f} ± {1e3 * line.slope_se_m:<7.3f}  "
                f"{line.r_squared_fitlm_robust:>15.4f}  {line.r_squared_ols:>8.4f}  "
                f"{line.robust_scale_nm:>10.4f}"
            )
        lines.append(
            "  R² fitlm-robust = SSR/(SSR + dfe·s²) as MATLAB fitlm(...,'RobustOpts','on') reports it; "
            "R² OLS = corr(tension, torque)²."
        )
        if self.k is None:
            lines.append("Implied friction: none (the raising slope is not above the lowering slope).")
        else:
            lines.append(
                f"Implied friction: k = mu·sin(phi/2) = {self.k:.4f} "
                f"(raising/lowering slope ratio {self.raising.slope_m / self.lowering.slope_m:.4f})."
            )
        verdict = "consistent with one k" if self.consistent_with_one_k else "NOT consistent with one k"
        lines.append(
            f"Single-bend check: sqrt(m_raise·m_lower) = {1e3 * self.geometric_mean_slope_m:.3f} mm vs "
            f"pulley radius {1e3 * self.pulley_radius_m:.3f} mm ({100 * self.radius_deviation:+.1f} %): "
            f"{verdict}."
        )
        if self.warnings:
            lines.append("Warnings:")
            lines.extend(f"  ! {warning}" for warning in self.warnings)
        return "\n".join(lines)


def _direction_warnings(line: DirectionSummary, thresholds: SummaryThresholds) -> list[str]:
    warnings = []
    if line.n < thresholds.min_samples:
        warnings.append(
            f"{line.direction}: only {line.n} steady-state samples (< {thresholds.min_samples}); "
            "record more or longer constant-speed sweeps"
        )
    worst = min(line.r_squared_ols, line.r_squared_fitlm_robust)
    if worst < thresholds.min_r_squared:
        warnings.append(
            f"{line.direction}: poor fit, R² = {worst:.4f} (< {thresholds.min_r_squared:g}); the "
            "torque-tension relation is not linear or the selection lets transients through"
        )
    if line.rejected_fraction > thresholds.max_rejected_fraction:
        warnings.append(
            f"{line.direction}: the robust fit rejected {100 * line.rejected_fraction:.1f} % of the "
            "samples as outliers; look at the figure for other populations (stick-slip, a slack cable, "
            "or lines fanning out with speed: friction that depends on velocity)"
        )
    if not line.converged:
        warnings.append(f"{line.direction}: robustfit hit its iteration limit without converging")
    return warnings


def identification_summary(
    raising_fit: RobustFit,
    lowering_fit: RobustFit,
    *,
    pulley_radius_m: float,
    thresholds: SummaryThresholds | None = None,
) -> IdentificationSummary:
    """Summarise two robust line fits (raising, lowering) against the single-bend law."""
    thresholds = thresholds or SummaryThresholds()
    if not (math.isfinite(pulley_radius_m) and pulley_radius_m > 0.0):
        raise ParameterError(f"pulley_radius_m must be positive, got {pulley_radius_m!r}")
    raising = DirectionSummary.from_fit(RAISING, raising_fit)
    lowering = DirectionSummary.from_fit(LOWERING, lowering_fit)
    warnings = _direction_warnings(raising, thresholds) + _direction_warnings(lowering, thresholds)
    k: float | None = None
    if raising.slope_m > 0.0 and lowering.slope_m > 0.0:
        geometric_mean = math.sqrt(raising.slope_m * lowering.slope_m)
        if raising.slope_m >= lowering.slope_m:
            k = friction_from_slopes(raising.slope_m, lowering.slope_m)
    else:
        geometric_mean = math.nan
    if k is None:
        warnings.append(
            "the raising slope is not above the lowering slope: sheath friction cannot explain that; "
            "check the sign of motor_velocity_rad_s (> 0 must reel the cable in)"
        )
    deviation = geometric_mean / pulley_radius_m - 1.0
    consistent = k is not None and abs(deviation) <= thresholds.radius_tolerance
    if k is not None and not consistent:
        warnings.append(
            f"the slopes do not fit one friction factor: their geometric mean is "
            f"{100 * deviation:+.1f} % off the {1e3 * pulley_radius_m:g} mm pulley radius (torque-constant "
            "error, wrong pulley radius, or losses the single-bend law does not describe)"
        )
    return IdentificationSummary(
        raising=raising,
        lowering=lowering,
        pulley_radius_m=pulley_radius_m,
        k=k,
        geometric_mean_slope_m=geometric_mean,
        radius_deviation=deviation,
        consistent_with_one_k=consistent,
        warnings=tuple(warnings),
    )
