"""Physics invariants of the simulated plant, against hand-derived values and the paper's law."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from bowden.sim import _kernels as k
from bowden.sim.parameters import (
    ArmParameters,
    MotorParameters,
    SheathParameters,
    SuitParameters,
    TransmissionParameters,
)
from bowden.sim.plant import Plant

R = 0.035


def torque_command(torque_nm: float) -> np.ndarray:
    return np.array([torque_nm, 0.0, 0.0, 0.0, 0.0])


def hold(plant: Plant, n: int, torque_nm: float, elevation_rad: float) -> np.ndarray:
    return plant.integrate(
        n, motor_mode=k.MOTOR_TORQUE, command=torque_command(torque_nm), arm_mode=k.ARM_PRESCRIBED,
        arm_a=np.full(n, elevation_rad), arm_b=np.zeros(n),
    )


def frictionless(**motor: float) -> SuitParameters:
    return SuitParameters(
        motor=MotorParameters(coulomb_friction_nm=0.0, viscous_friction_nms_rad=0.0, **motor),
        sheath=SheathParameters(kinetic_coefficient=0.0, static_to_kinetic_ratio=1.0),
    )


@pytest.mark.parametrize("ratio", [1.0, 0.85])
def test_static_equilibrium_without_friction_is_torque_over_radius(ratio: float) -> None:
    # Hand-derived: no friction anywhere, arm held still → T_in = T_out = kt·τ/R at rest.
    th = math.radians(60.0)
    plant = Plant(frictionless(torque_constant_ratio=ratio), ArmParameters(), elevation_rad=th, tension_n=5.0)
    hold(plant, 40000, 1.0, th)  # 10 s: the undamped rotor rings down through the distal damper
    state = plant.state()
    assert state.anchor_tension_n == pytest.approx(ratio * 1.0 / R, rel=1e-6)
    assert state.sheath_entry_tension_n == pytest.approx(ratio * 1.0 / R, rel=1e-6)


@pytest.mark.parametrize("torque_nm", [0.2, 0.5, 1.5])
def test_static_equilibrium_with_friction_lies_inside_both_friction_bands(torque_nm: float) -> None:
    # At rest the rotor balances within its Coulomb band, R·T_in ∈ [τ − τ_c, τ + τ_c], and the stuck
    # sheath within its static cone, T_out/T_in ∈ [(1 − k_s)/(1 + k_s), (1 + k_s)/(1 − k_s)].
    suit = SuitParameters()
    th = math.radians(70.0)
    plant = Plant(suit, ArmParameters(), elevation_rad=th, tension_n=12.0)
    hold(plant, 20000, torque_nm, th)
    state = plant.state()
    assert state.spool_velocity_rad_s == 0.0 and state.sheath_stuck
    coulomb = suit.motor.coulomb_friction_nm
    assert torque_nm - coulomb - 1e-9 <= R * state.sheath_entry_tension_n <= torque_nm + coulomb + 1e-9
    ks = suit.sheath.static_coefficient
    ratio = state.anchor_tension_n / state.sheath_entry_tension_n
    assert (1 - ks) / (1 + ks) - 1e-9 <= ratio <= (1 + ks) / (1 - ks) + 1e-9


def test_cable_cannot_push() -> None:
    th = math.radians(45.0)
    plant = Plant(SuitParameters(), ArmParameters(), elevation_rad=th, tension_n=20.0)
    record = hold(plant, 8000, -1.0, th)  # the motor "pushes": the cable must go slack, never negative
    assert np.all(record[:, k.R_T_OUT] >= 0.0)
    state = plant.state()
    assert state.anchor_tension_n == 0.0
    assert state.sheath_entry_tension_n == 0.0
    # A free mannequin arm under its own weight falls: a slack cable holds nothing up.
    arm = ArmParameters(gravity_torque_nm=2.0, damping_nms_rad=0.5)
    plant = Plant(SuitParameters(), arm, elevation_rad=th, tension_n=20.0)
    n = 8000
    plant.integrate(
        n, motor_mode=k.MOTOR_OFF, command=torque_command(0.0), arm_mode=k.ARM_TORQUE,
        arm_a=np.zeros(n), arm_b=np.zeros(n),
    )
    assert plant.state().elevation_rad < th - 0.3


def test_sheath_sticks_below_breakaway_and_slips_above() -> None:
    sheath = SheathParameters(kinetic_coefficient=0.12, static_to_kinetic_ratio=1.4)
    suit = replace(frictionless(), sheath=sheath)
    th = math.radians(60.0)
    t0 = 10.0
    plant = Plant(suit, ArmParameters(), elevation_rad=th, tension_n=t0)
    ks = sheath.static_coefficient
    breakaway = t0 * (1 + ks) / (1 - ks)  # T_in at which |T_in − T_out| = k_s·(T_in + T_out)
    seen_stuck, seen_slip = [], []
    for torque in np.linspace(R * t0, R * 1.3 * breakaway, 120):
        hold(plant, 400, float(torque), th)  # 0.1 s per level: the rotor settles on the cable
        state = plant.state()
        ratio_in = state.sheath_entry_tension_n / breakaway
        if ratio_in < 0.99:
            assert state.sheath_stuck, f"slipped at {ratio_in:.3f} of breakaway"
            assert state.anchor_tension_n == pytest.approx(t0, rel=1e-9)
            seen_stuck.append(ratio_in)
        elif ratio_in > 1.01:
            assert state.anchor_tension_n > t0 * 1.01, "no slip above breakaway"
            seen_slip.append(ratio_in)
    assert seen_stuck and seen_slip


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_sliding_follows_the_papers_single_bend_law(direction: float) -> None:
    # Supplement eq. S5: T_out = T_in (1 − k)/(1 + k) raising, (1 + k)/(1 − k) lowering, at speeds far
    # above the Stribeck velocity.
    kin = 0.12
    sheath = SheathParameters(kinetic_coefficient=kin, static_to_kinetic_ratio=1.3)
    suit = replace(frictionless(), sheath=sheath)
    th0 = math.radians(60.0)
    plant = Plant(suit, ArmParameters(), elevation_rad=th0, tension_n=20.0)
    n = 4000
    t = (np.arange(n) + 1) * suit.substep_s
    speed = 0.5 * direction
    plant.integrate(
        n, motor_mode=k.MOTOR_TORQUE, command=torque_command(0.7), arm_mode=k.ARM_PRESCRIBED,
        arm_a=th0 + speed * t, arm_b=np.full(n, speed),
    )
    state = plant.state()
    assert not state.sheath_stuck
    expected = (1 - kin) / (1 + kin) if direction > 0 else (1 + kin) / (1 - kin)
    assert state.anchor_tension_n / state.sheath_entry_tension_n == pytest.approx(expected, rel=1e-3)


def cycle_energy(substep_s: float) -> tuple[float, float, float]:
    suit = SuitParameters(substep_s=substep_s)
    th0, amp, f = math.radians(60.0), math.radians(30.0), 1.0
    plant = Plant(suit, ArmParameters(), elevation_rad=th0, tension_n=15.0)
    start = plant.state()
    n = round(2.0 / substep_s)  # two whole cycles: the arm ends where it started
    t = (np.arange(n) + 1) * substep_s
    record = plant.integrate(
        n, motor_mode=k.MOTOR_TORQUE, command=torque_command(0.5), arm_mode=k.ARM_PRESCRIBED,
        arm_a=th0 + amp * np.sin(2 * np.pi * f * t), arm_b=amp * 2 * np.pi * f * np.cos(2 * np.pi * f * t),
    )
    assert record.shape[0] == n
    end = plant.state()
    stored = end.elastic_energy_j(suit) - start.elastic_energy_j(suit)
    supplied = end.spool_work_j - end.arm_work_j
    dissipated = end.sheath_dissipated_j + end.distal_damper_dissipated_j
    return supplied, stored + dissipated, end.sheath_dissipated_j


def test_energy_balance_of_the_cable_and_sheath() -> None:
    supplied, accounted, sheath = cycle_energy(2.5e-4)
    assert sheath > 0.1  # friction did real work
    assert supplied == pytest.approx(accounted, rel=0.03)
    fine_supplied, fine_accounted, _ = cycle_energy(2.5e-5)
    # First-order scheme: the imbalance shrinks with the step.
    assert abs(fine_supplied - fine_accounted) < 0.3 * abs(supplied - accounted)


def test_sheath_dissipation_never_decreases() -> None:
    suit = SuitParameters()
    plant = Plant(suit, ArmParameters(), elevation_rad=1.0, tension_n=15.0)
    losses = []
    for i in range(200):
        th = 1.0 + 0.4 * math.sin(i / 15.0)
        hold(plant, 20, 0.5, th)
        losses.append(plant.state().sheath_dissipated_j)
    assert np.all(np.diff(losses) >= -1e-12)


def test_no_chatter_at_rest() -> None:
    th = math.radians(50.0)
    plant = Plant(SuitParameters(), ArmParameters(), elevation_rad=th, tension_n=8.0)
    hold(plant, 4000, 0.4, th)
    record = hold(plant, 4000, 0.4, th)
    assert np.all(record[:, k.R_SPOOL_W] == 0.0)
    assert np.ptp(record[:, k.R_T_OUT]) == 0.0


@pytest.mark.parametrize(
    ("cable", "distal", "inertia", "rotor"),
    [(1e6, 1e5, 2e-3, 2e-5), (1e3, 200.0, 5.0, 0.05), (1e6, 200.0, 2e-3, 0.05), (1e3, 1e5, 5.0, 2e-5)],
)
def test_no_blow_up_at_the_corners_of_the_documented_ranges(
    cable: float, distal: float, inertia: float, rotor: float
) -> None:
    suit = SuitParameters(
        motor=MotorParameters(rotor_inertia_kgm2=rotor),
        transmission=TransmissionParameters(
            cable_stiffness_n_m=cable, distal_stiffness_n_m=distal, distal_damping_ns_m=0.0
        ),
        substep_s=5e-4,
    )
    arm = ArmParameters(inertia_kgm2=inertia, gravity_torque_nm=1.0)
    plant = Plant(suit, arm, elevation_rad=1.0, tension_n=10.0)
    n = 6000
    t = np.arange(n) * suit.substep_s
    record = plant.integrate(
        n, motor_mode=k.MOTOR_TORQUE, command=torque_command(0.5), arm_mode=k.ARM_TORQUE,
        arm_a=2.0 * np.sin(5.0 * t), arm_b=np.zeros(n),
    )
    assert np.all(np.isfinite(record))
    assert np.max(record[:, k.R_T_OUT]) < 2000.0
    assert record[:, k.R_TH].min() > 0.0 - 0.2 and record[:, k.R_TH].max() < math.radians(140.0) + 0.2
