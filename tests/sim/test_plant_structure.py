"""The plant's structural variants (issue 28) against hand-derived values; defaults change nothing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bowden.errors import ParameterError
from bowden.sim import _kernels as k
from bowden.sim.parameters import ArmParameters, MotorParameters, SuitParameters
from bowden.sim.plant import Plant, pack_parameters
from bowden.sim.plant_family_structural import RANGES, random_structural_plants, structural_plants
from bowden.sim.plant_structure import PlantStructure

TH = math.radians(60.0)


def hold(plant: Plant, n: int, torque_nm: float, elevation_rad: float = TH) -> np.ndarray:
    return plant.integrate(
        n, motor_mode=k.MOTOR_TORQUE, command=np.array([torque_nm, 0.0, 0.0, 0.0, 0.0]),
        arm_mode=k.ARM_PRESCRIBED, arm_a=np.full(n, elevation_rad), arm_b=np.zeros(n),
    )


def test_default_structure_packs_the_nominal_plant() -> None:
    p = pack_parameters(SuitParameters(), ArmParameters())
    assert p[k.P_STRIBECK_EXP] == 2.0
    for index in (k.P_PRESLIDE_M, k.P_VISCOUS_LOAD, k.P_WRAP_GAIN, k.P_TENSION_GAIN, k.P_PLAY_M,
                  k.P_SHEATH_COMPLIANCE, k.P_KT_TEMPCO, k.P_THERMAL_TAU):
        assert p[index] == 0.0
    assert k.friction_scale(p, 1.2, 40.0, 30.0) == 1.0


@pytest.mark.parametrize("exponent", [0.5, 2.0, 3.0])
def test_stribeck_shape_follows_its_exponent(exponent: float) -> None:
    suit = SuitParameters(structure=PlantStructure(stribeck_exponent=exponent))
    p = pack_parameters(suit, ArmParameters())
    ks, kk, vs = p[k.P_K_STATIC], p[k.P_K_KINETIC], p[k.P_V_STRIBECK]
    # Hand-derived: k(v) = k_k + (k_s − k_k)·exp(−(v/v_s)^δ); at v = v_s the exponent does not matter.
    assert k.stribeck_coefficient(p, vs) == pytest.approx(kk + (ks - kk) * math.exp(-1.0), rel=1e-12)
    assert k.stribeck_coefficient(p, 2.0 * vs) == pytest.approx(kk + (ks - kk) * math.exp(-(2.0**exponent)))


def test_capstan_friction_grows_with_wrap_and_tension() -> None:
    suit = SuitParameters(structure=PlantStructure(wrap_gain_per_rad=0.5, tension_gain_per_n=0.01))
    p = pack_parameters(suit, ArmParameters())
    # 1 + 0.5·1.0 + 0.01·(40 + 20)/2 = 1.8, below the bound 0.9/k_s.
    assert k.friction_scale(p, 1.0, 40.0, 20.0) == pytest.approx(1.8)
    assert k.friction_scale(p, 1.0, 800.0, 800.0) == pytest.approx(0.9 / p[k.P_K_STATIC])


def test_dahl_presliding_moves_the_stuck_cable_elastically() -> None:
    """A load change inside the friction cone: a rigid stick holds the node still; with presliding
    the node yields by a fraction of the presliding length and the sheath still sticks."""
    moved = {}
    for presliding in (0.0, 1e-3):
        suit = SuitParameters(structure=PlantStructure(presliding_m=presliding))
        plant = Plant(suit, ArmParameters(), elevation_rad=TH, tension_n=30.0)
        start = float(plant.state_vector[k.X_NODE_S])
        hold(plant, 2000, 30.0 * 0.035 * 1.15)  # 15 % more torque: inside the cone (k_s = 0.13)
        assert plant.state().sheath_stuck
        moved[presliding] = float(plant.state_vector[k.X_NODE_S]) - start
    assert moved[0.0] == 0.0
    assert 2e-5 < moved[1e-3] < 1e-3


def test_sheath_compliance_compresses_at_rest() -> None:
    suit = SuitParameters(structure=PlantStructure(sheath_compliance_m_n=2e-5))
    plant = Plant(suit, ArmParameters(), elevation_rad=TH, tension_n=50.0)
    x, p = plant.state_vector, plant.vector
    # Hand-derived: the spool holds the node plus the cable's stretch plus the sheath's compression.
    expected = (x[k.X_NODE_S] + 50.0 / p[k.P_K_CABLE] + 2e-5 * 50.0) / p[k.P_SPOOL_R]
    assert x[k.X_SPOOL_Q] == pytest.approx(expected, rel=1e-12)
    hold(plant, 4000, 50.0 * 0.035)
    assert plant.state().anchor_tension_n == pytest.approx(50.0, rel=0.02)  # held: nothing moved


def test_warm_motor_loses_torque_the_driver_does_not_report() -> None:
    structure = PlantStructure(kt_tempco_per_k=0.001, heating_k_nm2=10.0, thermal_time_constant_s=5.0)
    plant = Plant(SuitParameters(structure=structure), ArmParameters(), elevation_rad=TH, tension_n=20.0)
    record = hold(plant, 80000, 1.0)  # 20 s = 4 time constants
    rise = float(plant.state_vector[k.X_TEMP_RISE])
    # Steady rise heating·τ² with τ ≈ (1 − 0.001·rise): solved by hand ≈ 9.81 K; after 4 τ 98 % there.
    assert rise == pytest.approx(0.98 * 9.81, rel=0.02)
    delivered = record[-1, k.R_MOTOR_TAU]
    assert delivered == pytest.approx(1.0 - 0.001 * rise, rel=1e-3)
    assert record[-1, k.R_REPORTED_TAU] == pytest.approx(1.0, rel=1e-3)


@pytest.mark.parametrize("torque_constant_ratio", [0.9, 1.1])
def test_driver_saturates_its_current_not_the_torque_it_delivers(torque_constant_ratio: float) -> None:
    """An AK driver limits its current: a command beyond the 9 Nm peak reports 9 Nm (current times the
    constant it assumes) and delivers 9 Nm times the true, warm constant's ratio to it; neither the
    report nor the current can exceed the peak as the constant falls (structural-32-0 reported 57.7 Nm)."""
    structure = PlantStructure(kt_tempco_per_k=0.001, heating_k_nm2=10.0, thermal_time_constant_s=5.0)
    suit = SuitParameters(structure=structure,
                          motor=MotorParameters(torque_constant_ratio=torque_constant_ratio))
    plant = Plant(suit, ArmParameters(), elevation_rad=TH, tension_n=20.0)
    record = hold(plant, 8000, 20.0)  # 2 s: the winding warms by tens of kelvin
    rise = float(plant.state_vector[k.X_TEMP_RISE])
    assert rise > 20.0
    limit_nm = suit.motor.torque_limit_nm
    # The report trails the constant's fall by the 1 ms current loop (~1e-4 here), nothing more.
    assert np.abs(record[:, k.R_REPORTED_TAU]).max() <= limit_nm * (1.0 + 1e-3)
    assert record[-1, k.R_REPORTED_TAU] == pytest.approx(limit_nm, rel=1e-3)
    expected_nm = limit_nm * torque_constant_ratio * (1.0 - 0.001 * rise)
    assert record[-1, k.R_MOTOR_TAU] == pytest.approx(expected_nm, rel=1e-3)


def test_structure_rejects_out_of_range() -> None:
    with pytest.raises(ParameterError, match=r"PlantStructure\.presliding_m"):
        PlantStructure(presliding_m=0.1)


def test_structural_family_is_inside_its_ranges() -> None:
    named = structural_plants()
    assert len({plant.name for plant in named}) == len(named)
    low, high = RANGES["imu_latency_s"]
    for plant in random_structural_plants(20, 3):
        s = plant.suit.structure
        assert RANGES["presliding_m"][0] <= s.presliding_m <= RANGES["presliding_m"][1]
        assert low <= plant.suit.imu.latency_s <= high
        assert plant.suit.sheath.static_coefficient <= 0.59 + 1e-12
