"""The held-out family: suits whose friction and motor differ from the compensation's law in structure.

The family of :mod:`bowden.sim.plant_family` varies the parameters of the nominal plant, which has
the same structure as the dynamic compensation (Coulomb lines, linear drag, inertia). This family
(issue 28) adds what the compensation does not model (:class:`bowden.sim.plant_structure.PlantStructure`):
Dahl presliding, capstan friction growing with wrap and tension, Stribeck curves of several shapes,
load-dependent drag, sheath play and compliance, a torque constant drifting as the motor warms — and
IMU latencies of 5–80 ms with up to three times the nominal IMU noise.

The ranges below (:data:`RANGES`) were fixed and committed before any compensation was evaluated on
this family; they must not be tuned to results. :func:`structural_plants` gives named suits that
each push one structure to a strong setting and :func:`random_structural_plants` suits drawn from all
ranges at once.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Final

import numpy as np

from bowden.model import CuffGeometry
from bowden.sim.parameters import (
    ImuParameters,
    MotorParameters,
    SheathParameters,
    SuitParameters,
    TransmissionParameters,
)
from bowden.sim.plant_family import FamilyPlant, family_rng
from bowden.sim.plant_structure import PlantStructure

# (low, high) of each drawn quantity; "log" ones are drawn log-uniformly. Fixed before evaluation.
RANGES: Final[dict[str, tuple[float, float]]] = {
    "kinetic_coefficient": (0.05, 0.2),
    "static_to_kinetic_ratio": (1.0, 1.6),
    "stribeck_velocity_m_s (log)": (1e-3, 1e-2),
    "stribeck_exponent": (0.5, 3.0),
    "viscous_coefficient_ns_m (log)": (5.0, 60.0),
    "viscous_per_newton_ns_m_n": (0.0, 0.5),
    "presliding_m": (0.0, 2e-3),
    "wrap_gain_per_rad": (0.0, 0.6),
    "tension_gain_per_n": (0.0, 0.01),
    "play_m": (0.0, 2e-3),
    "play_compliance_m_n": (2e-5, 2e-4),
    "sheath_compliance_m_n": (0.0, 2e-5),
    "kt_tempco_per_k": (0.0008, 0.0015),
    "heating_k_nm2": (2.0, 15.0),
    "thermal_time_constant_s": (60.0, 600.0),
    "motor_coulomb_nm": (0.05, 0.2),
    "torque_constant_ratio": (0.9, 1.1),
    "rotor_inertia_kgm2": (1e-3, 2.5e-3),
    "cable_stiffness_n_m (log)": (1.5e4, 6e4),
    "distal_stiffness_n_m (log)": (3e3, 2e4),
    "imu_latency_s": (0.005, 0.08),
    "imu_noise_factor": (1.0, 3.0),
    "exit_distance_m": (0.10, 0.14),
    "anchor_distance_m": (0.15, 0.21),
}


def noisy_imu(latency_s: float, noise_factor: float) -> ImuParameters:
    """The nominal IMU with ``latency_s`` and its elevation and rate noise times ``noise_factor``."""
    base = ImuParameters()
    return replace(
        base,
        latency_s=latency_s,
        elevation_noise_rad=base.elevation_noise_rad * noise_factor,
        velocity_noise_rad_s=base.velocity_noise_rad_s * noise_factor,
    )


def structural_plants() -> tuple[FamilyPlant, ...]:
    """Named suits, each with one structure the compensation does not model, set strongly."""
    base = SuitParameters()
    sheath = base.sheath

    def plant(name: str, description: str, structure: PlantStructure, **parts: object) -> FamilyPlant:
        return FamilyPlant(name, description, replace(base, structure=structure, **parts))  # type: ignore[arg-type]

    return (
        plant("dahl", "Dahl presliding over 1 mm, breakaway ×1.4", PlantStructure(presliding_m=1e-3),
              sheath=replace(sheath, static_to_kinetic_ratio=1.4)),
        plant("capstan", "friction growing with wrap (+50 %/rad) and tension (+0.6 %/N), k = 0.08",
              PlantStructure(wrap_gain_per_rad=0.5, tension_gain_per_n=0.006),
              sheath=replace(sheath, kinetic_coefficient=0.08)),
        plant("stribeck-sharp", "Stribeck exponent 0.5, breakaway ×1.5",
              PlantStructure(stribeck_exponent=0.5), sheath=replace(sheath, static_to_kinetic_ratio=1.5)),
        plant("stribeck-slow", "Stribeck exponent 3 over 10 mm/s, breakaway ×1.5",
              PlantStructure(stribeck_exponent=3.0),
              sheath=replace(sheath, static_to_kinetic_ratio=1.5,
                             stribeck_velocity_m_s=1e-2)),
        plant("load-viscous", "drag 5 N·s/m + 0.4 N·s/m per newton of load",
              PlantStructure(viscous_per_newton_ns_m_n=0.4),
              sheath=replace(sheath, viscous_coefficient_ns_m=5.0)),
        plant("play", "1.5 mm play at the sheath's ends, sheath compressing 2 mm per 100 N",
              PlantStructure(play_m=1.5e-3, play_compliance_m_n=1e-4, sheath_compliance_m_n=2e-5)),
        plant("warm-kt", "torque constant −0.12 %/K, 10 K/Nm², 120 s",
              PlantStructure(kt_tempco_per_k=0.0012, heating_k_nm2=10.0, thermal_time_constant_s=120.0)),
        plant("imu-5ms-noisy", "IMU 5 ms late, 3× noise", PlantStructure(), imu=noisy_imu(0.005, 3.0)),
        plant("imu-80ms-noisy", "IMU 80 ms late, 3× noise", PlantStructure(), imu=noisy_imu(0.08, 3.0)),
        plant("all", "Dahl 0.8 mm, capstan, Stribeck 0.8, load drag, play, warm kt, IMU 25 ms ×2 noise",
              PlantStructure(presliding_m=8e-4, wrap_gain_per_rad=0.3, tension_gain_per_n=0.004,
                             stribeck_exponent=0.8, viscous_per_newton_ns_m_n=0.2, play_m=1e-3,
                             play_compliance_m_n=1e-4, sheath_compliance_m_n=1e-5, kt_tempco_per_k=0.0012,
                             heating_k_nm2=8.0, thermal_time_constant_s=180.0),
              imu=noisy_imu(0.025, 2.0)),
    )


def _uniform(rng: np.random.Generator, name: str) -> float:
    low, high = RANGES[name]
    if name.endswith("(log)"):
        return float(math.exp(rng.uniform(math.log(low), math.log(high))))
    return float(rng.uniform(low, high))


def random_structural_plants(count: int, seed: int) -> tuple[FamilyPlant, ...]:
    """``count`` suits with every structure drawn from :data:`RANGES` at once."""
    rng = family_rng(count, seed)
    plants = []
    for index in range(count):
        u = {name: _uniform(rng, name) for name in RANGES}
        kinetic = u["kinetic_coefficient"]
        ratio = min(u["static_to_kinetic_ratio"], 0.59 / kinetic)
        structure = PlantStructure(
            presliding_m=u["presliding_m"], stribeck_exponent=u["stribeck_exponent"],
            wrap_gain_per_rad=u["wrap_gain_per_rad"], tension_gain_per_n=u["tension_gain_per_n"],
            viscous_per_newton_ns_m_n=u["viscous_per_newton_ns_m_n"], play_m=u["play_m"],
            play_compliance_m_n=u["play_compliance_m_n"], sheath_compliance_m_n=u["sheath_compliance_m_n"],
            kt_tempco_per_k=u["kt_tempco_per_k"], heating_k_nm2=u["heating_k_nm2"],
            thermal_time_constant_s=u["thermal_time_constant_s"],
        )
        suit = SuitParameters(
            motor=MotorParameters(
                coulomb_friction_nm=u["motor_coulomb_nm"], torque_constant_ratio=u["torque_constant_ratio"],
                rotor_inertia_kgm2=u["rotor_inertia_kgm2"],
            ),
            sheath=SheathParameters(
                kinetic_coefficient=kinetic, static_to_kinetic_ratio=ratio,
                stribeck_velocity_m_s=u["stribeck_velocity_m_s (log)"],
                viscous_coefficient_ns_m=u["viscous_coefficient_ns_m (log)"],
            ),
            transmission=TransmissionParameters(
                cable_stiffness_n_m=u["cable_stiffness_n_m (log)"],
                distal_stiffness_n_m=u["distal_stiffness_n_m (log)"],
            ),
            imu=noisy_imu(u["imu_latency_s"], u["imu_noise_factor"]),
            geometry=CuffGeometry(
                exit_distance_m=u["exit_distance_m"], anchor_distance_m=u["anchor_distance_m"]
            ),
            structure=structure,
        )
        description = (
            f"k {kinetic:.3f} ×{ratio:.2f}, Stribeck δ {structure.stribeck_exponent:.1f}, Dahl "
            f"{1e3 * structure.presliding_m:.1f} mm, wrap +{100 * structure.wrap_gain_per_rad:.0f} %/rad, "
            f"tension +{100 * structure.tension_gain_per_n:.2f} %/N, drag "
            f"{suit.sheath.viscous_coefficient_ns_m:.0f}+{structure.viscous_per_newton_ns_m_n:.2f}/N, play "
            f"{1e3 * structure.play_m:.1f} mm, IMU {1e3 * suit.imu.latency_s:.0f} ms "
            f"×{u['imu_noise_factor']:.1f}"
        )
        plants.append(FamilyPlant(f"structural-{seed}-{index}", description, suit))
    return tuple(plants)
