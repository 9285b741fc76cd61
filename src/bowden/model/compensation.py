"""Inverse transmission model with friction compensation (paper, "Control architecture").

Two identified lines give the motor torque needed for a desired arm tension, one per direction of
cable travel, and a sigmoid in humeral elevation velocity blends them:

    τ = τ_low + (τ_raise − τ_low) · w(θ̇),   w(θ̇) = 1 / (1 + exp(−B·(θ̇ − M)))
    M = (θ̇₀₀₁ + θ̇₀₉₉)/2,                     B = ln(99) / (θ̇₀₉₉ − M)

so that w(θ̇₀₀₁) = 0.01 and w(θ̇₀₉₉) = 0.99, which is how the paper defines the blend. The paper prints
B = ln(99)/(θ̇₀₀₁ − M), which is negative and blends the wrong way round (REFERENCE §1); the defining
property is implemented, and tested.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from bowden.errors import ParameterError
from bowden.model.transmission import slopes_from_friction

LN_99 = math.log(99.0)


def _finite(name: str, value: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value)):
        raise ParameterError(f"{name} must be a finite number, got {value!r}")


@dataclass(frozen=True, kw_only=True)
class CompensationLine:
    """Motor torque for a desired arm tension in one direction: τ = intercept_nm + slope_m·T."""

    intercept_nm: float
    slope_m: float

    def __post_init__(self) -> None:
        _finite("intercept_nm", self.intercept_nm)
        _finite("slope_m", self.slope_m)
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
    fitlm's robust definition SSR/(SSR + dfe·s²) with the robust scale s (REFERENCE §1).
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
            _finite(name, getattr(self, name))


@dataclass(frozen=True, kw_only=True)
class Provenance:
    """Where a model came from: source files and their SHA-256, UTC creation time, tool and version."""

    source_files: tuple[str, ...] = ()
    source_sha256: tuple[str, ...] = ()
    created_utc: str = ""
    tool: str = "bowden"
    tool_version: str = ""
    notes: str = ""

    def __post_init__(self) -> None:
        if len(self.source_files) != len(self.source_sha256):
            raise ParameterError(
                f"source_files ({len(self.source_files)}) and source_sha256 "
                f"({len(self.source_sha256)}) must have the same length"
            )


@dataclass(frozen=True, kw_only=True)
class CompensationModel:
    """Raising and lowering lines blended by elevation velocity; the controller's inverse model.

    Parameters
    ----------
    raising, lowering
        Torque-vs-tension lines identified while raising and lowering.
    blend_velocity_01_rad_s, blend_velocity_99_rad_s
        Elevation velocities where the raising line has 1 % and 99 % weight (paper: −1, +1 rad/s).
    pulley_radius_m
        Spool radius (paper: 35 mm), used to relate torque and cable tension.
    raising_fit, lowering_fit, provenance
        Identification statistics and provenance, when the model came from data.
    """

    raising: CompensationLine
    lowering: CompensationLine
    blend_velocity_01_rad_s: float = -1.0
    blend_velocity_99_rad_s: float = 1.0
    pulley_radius_m: float = 0.035
    raising_fit: LineFitStats | None = None
    lowering_fit: LineFitStats | None = None
    provenance: Provenance | None = None
    blend_midpoint_rad_s: float = field(init=False, repr=False)
    blend_steepness_s_rad: float = field(init=False, repr=False)

    def __post_init__(self) -> None:
        _finite("blend_velocity_01_rad_s", self.blend_velocity_01_rad_s)
        _finite("blend_velocity_99_rad_s", self.blend_velocity_99_rad_s)
        if not self.blend_velocity_99_rad_s > self.blend_velocity_01_rad_s:
            raise ParameterError(
                "blend_velocity_99_rad_s must exceed blend_velocity_01_rad_s (the raising line takes "
                f"over as velocity grows); got {self.blend_velocity_01_rad_s!r} and "
                f"{self.blend_velocity_99_rad_s!r}"
            )
        _finite("pulley_radius_m", self.pulley_radius_m)
        if not 0.0 < self.pulley_radius_m < 0.5:
            raise ParameterError(f"pulley_radius_m must be in (0, 0.5) m, got {self.pulley_radius_m!r}")
        midpoint = 0.5 * (self.blend_velocity_01_rad_s + self.blend_velocity_99_rad_s)
        object.__setattr__(self, "blend_midpoint_rad_s", midpoint)
        object.__setattr__(self, "blend_steepness_s_rad", LN_99 / (self.blend_velocity_99_rad_s - midpoint))

    @classmethod
    def from_friction(
        cls,
        *,
        k: float,
        pulley_radius_m: float = 0.035,
        blend_velocity_01_rad_s: float = -1.0,
        blend_velocity_99_rad_s: float = 1.0,
    ) -> CompensationModel:
        """The ideal single-bend model for a friction factor k = μ·sin(φ/2), with zero intercepts."""
        slope_raising, slope_lowering = slopes_from_friction(k, pulley_radius_m)
        return cls(
            raising=CompensationLine(intercept_nm=0.0, slope_m=slope_raising),
            lowering=CompensationLine(intercept_nm=0.0, slope_m=slope_lowering),
            blend_velocity_01_rad_s=blend_velocity_01_rad_s,
            blend_velocity_99_rad_s=blend_velocity_99_rad_s,
            pulley_radius_m=pulley_radius_m,
        )

    def blend_weight(self, elevation_velocity_rad_s: float) -> float:
        """Weight of the raising line, w ∈ (0, 1); w(θ̇₀₀₁) = 0.01, w(θ̇₀₉₉) = 0.99."""
        x = self.blend_steepness_s_rad * (elevation_velocity_rad_s - self.blend_midpoint_rad_s)
        # Two branches so exp never overflows for large |x|.
        if x >= 0.0:
            return 1.0 / (1.0 + math.exp(-x))
        e = math.exp(x)
        return e / (1.0 + e)

    def torque_nm(self, tension_n: float, elevation_velocity_rad_s: float) -> float:
        """Motor torque that should produce ``tension_n`` at the arm at this elevation velocity."""
        lowering = self.lowering.torque_nm(tension_n)
        raising = self.raising.torque_nm(tension_n)
        return lowering + (raising - lowering) * self.blend_weight(elevation_velocity_rad_s)

    def save(self, path: str | Path) -> None:
        """Write the versioned ``model.json`` (see :mod:`bowden.model.model_file`)."""
        from bowden.model.model_file import save_model  # model_file imports this module

        save_model(self, path)

    @classmethod
    def load(cls, path: str | Path) -> CompensationModel:
        """Read a ``model.json``; raises :class:`bowden.errors.ModelFileError` naming any bad field."""
        from bowden.model.model_file import load_model  # model_file imports this module

        return load_model(path)
