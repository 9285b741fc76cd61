"""A family of simulated suits that differ where real suits differ, to judge a compensation honestly.

A compensation tuned on one simulator can exploit that simulator. Judged instead on suits that differ
in friction law, drag, stiffness, torque constant, IMU latency and cuff geometry — each identified on
its own bench first, as a lab would — a method only wins if it captures physics that transfers.
:func:`named_plants` are fixed variants around the default suit (which the dynamic compensation was
developed on; the others were not looked at while developing it), :func:`random_plants` draws suits
from the documented ranges of :mod:`bowden.sim.parameters` that nobody has seen before a run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from bowden.errors import ParameterError
from bowden.model import CuffGeometry
from bowden.sim.parameters import (
    ImuParameters,
    MotorParameters,
    SheathParameters,
    SuitParameters,
    TransmissionParameters,
    check_seed,
)

DEVELOPMENT_PLANT = "default"


@dataclass(frozen=True)
class FamilyPlant:
    """One suit of the family: a name, what differs, and its parameters."""

    name: str
    description: str
    suit: SuitParameters


def named_plants() -> tuple[FamilyPlant, ...]:
    """The default suit and variants that each change one aspect of it (or the friction law)."""
    base = SuitParameters()
    sheath, motor, transmission = base.sheath, base.motor, base.transmission

    def plant(name: str, description: str, **parts: object) -> FamilyPlant:
        return FamilyPlant(name, description, replace(base, **parts))  # type: ignore[arg-type]

    return (
        FamilyPlant(DEVELOPMENT_PLANT, "the default simulated suit (developed on)", base),
        plant(
            "coulomb",
            "single-bend Coulomb sheath: no breakaway, little drag",
            sheath=replace(sheath, static_to_kinetic_ratio=1.0, viscous_coefficient_ns_m=5.0),
        ),
        plant(
            "sticky",
            "strong stiction: breakaway 1.6× kinetic, slow Stribeck curve, k = 0.12",
            sheath=replace(
                sheath, kinetic_coefficient=0.12, static_to_kinetic_ratio=1.6, stribeck_velocity_m_s=1.0e-2
            ),
        ),
        plant(
            "high-friction",
            "capstan-like long routing: k = 0.2 (the plant's single bend stands in)",
            sheath=replace(sheath, kinetic_coefficient=0.2, static_to_kinetic_ratio=1.2),
        ),
        plant(
            "draggy",
            "viscous sheath: 60 N·s/m drag, k = 0.07",
            sheath=replace(sheath, kinetic_coefficient=0.07, viscous_coefficient_ns_m=60.0),
        ),
        plant(
            "stiff",
            "stiff cable and cuff: 6e4 and 2e4 N/m",
            transmission=replace(transmission, cable_stiffness_n_m=6.0e4, distal_stiffness_n_m=2.0e4),
        ),
        plant(
            "soft",
            "soft cable and tissue: 1.5e4 and 3e3 N/m",
            transmission=replace(transmission, cable_stiffness_n_m=1.5e4, distal_stiffness_n_m=3.0e3),
        ),
        plant(
            "kt+10",
            "torque constant 10 % above the driver's",
            motor=replace(motor, torque_constant_ratio=1.1),
        ),
        plant(
            "kt-10",
            "torque constant 10 % below the driver's",
            motor=replace(motor, torque_constant_ratio=0.9),
        ),
        plant("imu-10ms", "IMU samples 10 ms old", imu=replace(base.imu, latency_s=0.01)),
        plant("imu-40ms", "IMU samples 40 ms old", imu=replace(base.imu, latency_s=0.04)),
        plant(
            "cuff",
            "another cuff: anchor 0.15 m down the arm, exit 0.14 m above the shoulder",
            geometry=CuffGeometry(exit_distance_m=0.14, anchor_distance_m=0.15),
        ),
    )


def family_rng(count: int, seed: int) -> np.random.Generator:
    """The generator a family of ``count`` random suits is drawn from (1–100 suits, a valid seed)."""
    check_seed(seed)
    if not 1 <= count <= 100:
        raise ParameterError(f"count must be in [1, 100], got {count}")
    return np.random.default_rng(seed)


def random_plants(count: int, seed: int) -> tuple[FamilyPlant, ...]:
    """``count`` suits drawn uniformly (log-uniformly for stiffness and drag) from documented ranges."""
    rng = family_rng(count, seed)
    plants = []
    for index in range(count):
        kinetic = float(rng.uniform(0.05, 0.2))
        ratio = float(rng.uniform(1.0, min(1.6, 0.59 / kinetic)))
        suit = SuitParameters(
            motor=MotorParameters(
                coulomb_friction_nm=float(rng.uniform(0.05, 0.2)),
                torque_constant_ratio=float(rng.uniform(0.9, 1.1)),
                rotor_inertia_kgm2=float(rng.uniform(1.0e-3, 2.5e-3)),
            ),
            sheath=SheathParameters(
                kinetic_coefficient=kinetic,
                static_to_kinetic_ratio=ratio,
                stribeck_velocity_m_s=float(math.exp(rng.uniform(math.log(1e-3), math.log(1e-2)))),
                viscous_coefficient_ns_m=float(math.exp(rng.uniform(math.log(5.0), math.log(60.0)))),
            ),
            transmission=TransmissionParameters(
                cable_stiffness_n_m=float(math.exp(rng.uniform(math.log(1.5e4), math.log(6e4)))),
                distal_stiffness_n_m=float(math.exp(rng.uniform(math.log(3e3), math.log(2e4)))),
            ),
            imu=ImuParameters(latency_s=float(rng.uniform(0.01, 0.05))),
            geometry=CuffGeometry(
                exit_distance_m=float(rng.uniform(0.10, 0.14)),
                anchor_distance_m=float(rng.uniform(0.15, 0.21)),
            ),
        )
        s, t = suit.sheath, suit.transmission
        description = (
            f"k {s.kinetic_coefficient:.3f}, breakaway ×{s.static_to_kinetic_ratio:.2f}, drag "
            f"{s.viscous_coefficient_ns_m:.0f} N·s/m, cable {t.cable_stiffness_n_m:.3g} N/m, distal "
            f"{t.distal_stiffness_n_m:.3g} N/m, Kt ×{suit.motor.torque_constant_ratio:.2f}, IMU "
            f"{1e3 * suit.imu.latency_s:.0f} ms"
        )
        plants.append(FamilyPlant(f"random-{seed}-{index}", description, suit))
    return tuple(plants)
