"""Arm anthropometry (de Leva 1996) and the gravitational shoulder torque.

Segment masses, lengths and centre-of-mass positions come from de Leva P., "Adjustments to
Zatsiorsky-Seluyanov's segment inertia parameters", J Biomech 29(9):1223-1230, 1996, Table 4
(sex-specific; lengths given for a reference stature of 1741 mm men / 1735 mm women and scaled here
in proportion to the subject's stature). The hand's centre of mass is measured from the wrist
towards the third metacarpophalangeal joint.

The arm is modelled as a straight chain (elbow extended, as the paper instructs), so the
gravitational torque about the shoulder at humeral elevation θ (0 = arm hanging) is

    τ_g(θ) = g · sin θ · (Σ mᵢ·dᵢ + m_load·d_load)

with dᵢ the distance of segment i's centre of mass from the shoulder and the hand-held load at the
hand's centre of mass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from bowden.errors import ParameterError

STANDARD_GRAVITY_M_S2 = 9.80665

Sex = Literal["female", "male"]


@dataclass(frozen=True, kw_only=True)
class SegmentTable:
    """de Leva (1996) parameters of one segment for one sex.

    ``mass_fraction`` of body mass; ``com_fraction`` of segment length from the proximal end;
    ``length_m`` at the table's reference stature.
    """

    mass_fraction: float
    com_fraction: float
    length_m: float


# de Leva 1996, Table 4. Reference statures: men 1741 mm, women 1735 mm.
_REFERENCE_STATURE_M: dict[str, float] = {"male": 1.741, "female": 1.735}
_DE_LEVA: dict[str, dict[str, SegmentTable]] = {
    "male": {
        "upper_arm": SegmentTable(mass_fraction=0.0271, com_fraction=0.5772, length_m=0.2817),
        "forearm": SegmentTable(mass_fraction=0.0162, com_fraction=0.4574, length_m=0.2689),
        "hand": SegmentTable(mass_fraction=0.0061, com_fraction=0.7900, length_m=0.0862),
    },
    "female": {
        "upper_arm": SegmentTable(mass_fraction=0.0255, com_fraction=0.5754, length_m=0.2751),
        "forearm": SegmentTable(mass_fraction=0.0138, com_fraction=0.4559, length_m=0.2643),
        "hand": SegmentTable(mass_fraction=0.0056, com_fraction=0.7474, length_m=0.0780),
    },
}
SEGMENTS = ("upper_arm", "forearm", "hand")


@dataclass(frozen=True, kw_only=True)
class Subject:
    """A wearer's anthropometrics: stature (m), body mass (kg) and sex (for de Leva's tables).

    Pseudonymous by construction: no name field exists.
    """

    height_m: float
    mass_kg: float
    sex: Sex

    def __post_init__(self) -> None:
        if not (math.isfinite(self.height_m) and 1.0 <= self.height_m <= 2.3):
            raise ParameterError(
                f"height_m must be a stature in metres between 1.0 and 2.3, got {self.height_m!r}"
                + (" (centimetres?)" if isinstance(self.height_m, int | float) and self.height_m > 50 else "")
            )
        if not (math.isfinite(self.mass_kg) and 25.0 <= self.mass_kg <= 250.0):
            raise ParameterError(f"mass_kg must be between 25 and 250 kg, got {self.mass_kg!r}")
        if self.sex not in _DE_LEVA:
            raise ParameterError(f"sex must be 'female' or 'male', got {self.sex!r}")


@dataclass(frozen=True, kw_only=True)
class ArmSegment:
    """One segment scaled to a subject: mass (kg), length (m), CoM distance from the shoulder (m)."""

    name: str
    mass_kg: float
    length_m: float
    com_from_shoulder_m: float


@dataclass(frozen=True, kw_only=True)
class ArmModel:
    """The straight arm of a subject: segments, the hand-load lever and the static moments."""

    segments: tuple[ArmSegment, ...]
    hand_load_kg: float
    hand_load_lever_m: float

    @property
    def arm_moment_kg_m(self) -> float:
        """Σ mᵢ·dᵢ of the arm segments, kg·m."""
        return sum(s.mass_kg * s.com_from_shoulder_m for s in self.segments)

    @property
    def load_moment_kg_m(self) -> float:
        """m_load·d_load of the hand-held load, kg·m."""
        return self.hand_load_kg * self.hand_load_lever_m

    @property
    def total_moment_kg_m(self) -> float:
        return self.arm_moment_kg_m + self.load_moment_kg_m

    @property
    def moment_of_inertia_kg_m2(self) -> float:
        """Moment of inertia of the straight arm about the shoulder, kg·m².

        Each segment is a uniform rod about its own centre (m·L²/12) moved to the shoulder by the
        parallel-axis term; the load is a point mass. An approximation (de Leva's radii of gyration
        differ by some 10 %), adequate for a simulated arm.
        """
        segments = sum(
            s.mass_kg * (s.length_m**2 / 12.0 + s.com_from_shoulder_m**2) for s in self.segments
        )
        return segments + self.hand_load_kg * self.hand_load_lever_m**2

    def gravity_torque_nm(self, elevation_rad: float) -> float:
        """τ_g(θ) = g·sin θ·(Σ mᵢdᵢ + m_load·d_load), Nm, θ from arm-down."""
        return STANDARD_GRAVITY_M_S2 * math.sin(elevation_rad) * self.total_moment_kg_m


def arm_model(subject: Subject, hand_load_kg: float = 0.5) -> ArmModel:
    """Scale de Leva's segments to ``subject`` and place ``hand_load_kg`` at the hand's centre of mass."""
    if not (math.isfinite(hand_load_kg) and 0.0 <= hand_load_kg <= 20.0):
        raise ParameterError(f"hand_load_kg must be between 0 and 20 kg, got {hand_load_kg!r}")
    table = _DE_LEVA[subject.sex]
    scale = subject.height_m / _REFERENCE_STATURE_M[subject.sex]
    segments: list[ArmSegment] = []
    proximal_m = 0.0
    for name in SEGMENTS:
        row = table[name]
        length = row.length_m * scale
        segments.append(
            ArmSegment(
                name=name,
                mass_kg=row.mass_fraction * subject.mass_kg,
                length_m=length,
                com_from_shoulder_m=proximal_m + row.com_fraction * length,
            )
        )
        proximal_m += length
    return ArmModel(
        segments=tuple(segments),
        hand_load_kg=hand_load_kg,
        hand_load_lever_m=segments[-1].com_from_shoulder_m,
    )


def arm_gravity_torque_nm(subject: Subject, elevation_rad: float, hand_load_kg: float = 0.5) -> float:
    """Gravitational shoulder torque of ``subject``'s straight arm plus a hand-held load, Nm."""
    return arm_model(subject, hand_load_kg).gravity_torque_nm(elevation_rad)
