"""One identified line of the inverse transmission model and how well it was identified.

The paper's model (:mod:`bowden.model.compensation`) blends two of these; the dynamic model
(:mod:`bowden.model.dynamic`) keeps them as its load-proportional friction.
"""

from __future__ import annotations

from dataclasses import dataclass

from bowden.errors import ParameterError
from bowden.validation import check_number


@dataclass(frozen=True, kw_only=True)
class CompensationLine:
    """Motor torque for a desired arm tension in one direction: τ = intercept_nm + slope_m·T."""

    intercept_nm: float
    slope_m: float

    def __post_init__(self) -> None:
        check_number(self.intercept_nm, "intercept_nm")
        check_number(self.slope_m, "slope_m")
        if not (0.0 < self.slope_m < 1.0):
            raise ParameterError(
                f"slope_m is motor torque per newton of tension (about the pulley radius), "
                f"so it must be in (0, 1) m; got {self.slope_m!r}"
            )

    def torque_nm(self, tension_n: float) -> float:
        return self.intercept_nm + self.slope_m * tension_n


@dataclass(frozen=True, kw_only=True)
class LineFitStats:
    """How well a compensation line was identified.

    ``r_squared_ols`` is corr(y, ŷ)² (equal to ordinary R² for a line); ``r_squared_robust`` is
    fitlm's robust definition SSR/(SSR + dfe·s²) with the robust scale s (MATLAB fitlm with 'RobustOpts',
    "Coefficient of determination").
    """

    n: int
    r_squared_ols: float
    r_squared_robust: float
    robust_scale_nm: float
    intercept_se_nm: float
    slope_se_m: float

    def __post_init__(self) -> None:
        if not (isinstance(self.n, int) and self.n >= 0):
            raise ParameterError(f"n must be a non-negative integer, got {self.n!r}")
        for name in ("r_squared_ols", "r_squared_robust", "robust_scale_nm", "intercept_se_nm", "slope_se_m"):
            check_number(getattr(self, name), name)
