"""Inverse transmission model with friction compensation (paper, "Control architecture").

Two identified lines give the motor torque needed for a desired arm tension, one per direction of
cable travel, and a sigmoid in humeral elevation velocity blends them:

    τ = τ_low + (τ_raise − τ_low) · w(θ̇),   w(θ̇) = 1 / (1 + exp(−B·(θ̇ − M)))
    M = (θ̇₀₀₁ + θ̇₀₉₉)/2,                     B = ln(99) / (θ̇₀₉₉ − M)

so that w(θ̇₀₀₁) = 0.01 and w(θ̇₀₉₉) = 0.99, which is how the paper defines the blend. The paper prints
B = ln(99)/(θ̇₀₀₁ − M), which is negative and blends the wrong way round (paper, "Control architecture",
eq. of the sigmoid); the defining
property is implemented, and tested.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from bowden.errors import ParameterError
from bowden.model.dynamic import DynamicCompensation
from bowden.model.lines import CompensationLine, LineFitStats
from bowden.model.transmission import slopes_from_friction
from bowden.validation import check_number

LN_99 = math.log(99.0)


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
    dynamic
        The dynamic compensation identified from the same bench data (:mod:`bowden.model.dynamic`),
        or None. When present it is the model's recommended compensation: ``build_controller`` uses
        it unless asked for ``compensation="paper"``, which uses the lines above exactly as the paper.
    """

    raising: CompensationLine
    lowering: CompensationLine
    blend_velocity_01_rad_s: float = -1.0
    blend_velocity_99_rad_s: float = 1.0
    pulley_radius_m: float = 0.035
    raising_fit: LineFitStats | None = None
    lowering_fit: LineFitStats | None = None
    provenance: Provenance | None = None
    dynamic: DynamicCompensation | None = None
    blend_midpoint_rad_s: float = field(init=False, repr=False)
    blend_steepness_s_rad: float = field(init=False, repr=False)

    def __post_init__(self) -> None:
        check_number(self.blend_velocity_01_rad_s, "blend_velocity_01_rad_s")
        check_number(self.blend_velocity_99_rad_s, "blend_velocity_99_rad_s")
        if not self.blend_velocity_99_rad_s > self.blend_velocity_01_rad_s:
            raise ParameterError(
                "blend_velocity_99_rad_s must exceed blend_velocity_01_rad_s (the raising line takes "
                f"over as velocity grows); got {self.blend_velocity_01_rad_s!r} and "
                f"{self.blend_velocity_99_rad_s!r}"
            )
        check_number(self.pulley_radius_m, "pulley_radius_m")
        if not 0.0 < self.pulley_radius_m < 0.5:
            raise ParameterError(f"pulley_radius_m must be in (0, 0.5) m, got {self.pulley_radius_m!r}")
        if self.dynamic is not None and not isinstance(self.dynamic, DynamicCompensation):
            raise ParameterError(f"dynamic must be a DynamicCompensation or None, got {self.dynamic!r}")
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

    @property
    def recommended_compensation(self) -> str:
        """``"dynamic"`` when the model holds a dynamic compensation, else ``"paper"``."""
        return "paper" if self.dynamic is None else "dynamic"

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
