"""MyoArm in MuJoCo: moment arms, inverse dynamics and the cable against independent derivations."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mujoco")
pytest.importorskip("myo_sim")

from bowden.model import CuffGeometry
from bowden.sim.musculoskeletal.activations import electrode_activations, solve_state
from bowden.sim.musculoskeletal.myoarm import (
    ARM_MUSCLES,
    COORDINATES,
    ELBOW,
    ELEVATION,
    HAND_BODY,
    MyoArm,
)

ELEVATIONS_DEG = (30.0, 60.0, 90.0)
STEP_RAD = 1e-5


@pytest.fixture(scope="module")
def arm() -> MyoArm:
    return MyoArm()


@pytest.mark.parametrize("elevation_deg", ELEVATIONS_DEG)
def test_deltoid_moment_arms_are_the_models_length_derivatives(arm: MyoArm, elevation_deg: float) -> None:
    # A moment arm is −dL/dθ with the shoulder girdle following the humerus (the rhythm's
    # constraints): the central difference of MuJoCo's own musculotendon lengths, a path independent
    # of the actuator moments it reports.
    theta = math.radians(elevation_deg)
    arms = dict(
        zip(ARM_MUSCLES, arm.muscle_state(theta).moment_arm_m[COORDINATES.index(ELEVATION)], strict=True)
    )
    lengths = (arm.tendon_length_m(theta + STEP_RAD) - arm.tendon_length_m(theta - STEP_RAD)) / (2 * STEP_RAD)
    derivative = dict(zip(ARM_MUSCLES, -lengths, strict=True))
    for name in ("DELT1", "DELT2", "DELT3"):
        assert arms[name] == pytest.approx(derivative[name], abs=2e-5)
    # In forward flexion the anterior deltoid elevates and the posterior deltoid depresses the arm
    # (Holzbaur et al. 2005, Fig. 5: DELT1 a flexor, DELT3 an extensor below 90°).
    assert arms["DELT1"] > 0.01 and arms["DELT3"] < 0.0


def _potential_energy_j(arm: MyoArm, theta: float, hand_load_kg: float) -> float:
    arm.set_state(theta)
    m, d = arm.model, arm.data
    g = -float(m.opt.gravity[2])  # MyoArm's own 9.81 m/s²
    bodies = float(np.sum(m.body_mass * d.xipos[:, 2])) * g
    return bodies + hand_load_kg * g * float(d.xpos[m.body(HAND_BODY).id][2])


@pytest.mark.parametrize("elevation_deg", ELEVATIONS_DEG)
def test_holding_still_the_muscles_make_the_gravity_torque_by_virtual_work(
    arm: MyoArm, elevation_deg: float
) -> None:
    theta = math.radians(elevation_deg)
    required = arm.required_torques_nm(theta, 0.0, 0.0, hand_load_kg=0.5)
    gravity = (
        _potential_energy_j(arm, theta + STEP_RAD, 0.5) - _potential_energy_j(arm, theta - STEP_RAD, 0.5)
    ) / (2 * STEP_RAD)
    assert required[COORDINATES.index(ELEVATION)] == pytest.approx(gravity, rel=1e-4)
    assert 4.0 < gravity < 20.0  # arm and 0.5 kg, de Leva's order of magnitude


def test_the_cable_torque_is_its_tension_times_the_shortening_of_the_cable(arm: MyoArm) -> None:
    geometry = CuffGeometry()
    theta, tension = math.radians(60.0), 50.0

    def length(angle: float) -> float:  # the exit rides with the glenohumeral centre
        arm.set_state(angle)
        anchor, exit_point = arm.cuff_points(geometry)
        return float(np.linalg.norm(exit_point - anchor))

    shortening = -(length(theta + STEP_RAD) - length(theta - STEP_RAD)) / (2 * STEP_RAD)
    assert arm.cable_torque_nm(theta, tension, geometry) == pytest.approx(tension * shortening, rel=1e-4)
    with_cable = arm.required_torques_nm(theta, 0.0, 0.0, hand_load_kg=0.5, cable_tension_n=tension)
    without = arm.required_torques_nm(theta, 0.0, 0.0, hand_load_kg=0.5)
    k = COORDINATES.index(ELEVATION)
    assert without[k] - with_cable[k] == pytest.approx(tension * shortening, rel=1e-4)


@pytest.mark.parametrize("elevation_deg", [20.0, 60.0, 100.0, 130.0])
def test_the_cable_torque_is_the_controllers_moment_arm_times_the_tension(
    arm: MyoArm, elevation_deg: float
) -> None:
    # The simulated plant moves the arm with r(θ)·T (CuffGeometry); the muscles must balance the same
    # cable. With the exit fixed to the trunk it was 3-35 % larger (the joint centre rises).
    geometry, theta = CuffGeometry(), math.radians(elevation_deg)
    expected = 50.0 * geometry.moment_arm_m(theta)
    assert arm.cable_torque_nm(theta, 50.0, geometry) == pytest.approx(expected, rel=0.04)


def test_static_optimisation_balances_the_arm_and_the_cable_relieves_the_deltoid(arm: MyoArm) -> None:
    theta = math.radians(60.0)
    alone = solve_state(arm, theta, 0.0, 0.0, hand_load_kg=0.5)
    state = arm.muscle_state(theta)
    made = state.moment_arm_m @ (state.active_force_n * alone.activations + state.passive_force_n)
    required = arm.required_torques_nm(theta, 0.0, 0.0, hand_load_kg=0.5)
    required[COORDINATES.index(ELBOW)] = min(required[COORDINATES.index(ELBOW)], 0.0)  # the extension stop
    np.testing.assert_allclose(made + alone.reserve_nm, required, atol=1e-4)
    assert np.abs(alone.reserve_nm).max() < 1e-3
    supported = solve_state(arm, theta, 0.0, 0.0, hand_load_kg=0.5, cable_tension_n=60.0)
    before, after = (
        electrode_activations(alone.activations, arm.max_force_n),
        electrode_activations(supported.activations, arm.max_force_n),
    )
    assert after[0] < 0.7 * before[0]  # anterior deltoid


# MoBL's own moment arms about shoulder_elv in forward flexion (elv_angle 90°, no rotation, elbow
# extended), mm, computed by OpenSim 4.6 from the original MoBL-ARMS OpenSim model (Holzbaur et al.
# 2005; the OpenSim 3.3 tutorial model MoBL_ARMS_module6_7_CMC.osim of Saul et al. 2015, sha256
# 93f49919…) with scripts/mobl_moment_arms.py.
MOBL_OPENSIM_MOMENT_ARMS_MM = {
    30.0: {"DELT1": 44.11, "DELT2": 19.58, "DELT3": -24.13},
    60.0: {"DELT1": 40.79, "DELT2": 24.38, "DELT3": -17.79},
    90.0: {"DELT1": 22.13, "DELT2": 40.04, "DELT3": -11.77},
}
# The MuJoCo translation's DELT1 and DELT3 agree within this (≈ 12 % of the largest deltoid moment
# arm, 45 mm). Its DELT2 does not: MyoArm's medial deltoid path gives 63 / 77 / 50 % of MoBL's moment
# arm at 30 / 60 / 90° (12.4 / 18.8 / 20.1 against 19.6 / 24.4 / 40.0 mm), a departure of the
# translation that is checked below, so that a change of either model is noticed.
MOMENT_ARM_TOLERANCE_MM = 5.5


@pytest.mark.parametrize("elevation_deg", ELEVATIONS_DEG)
def test_deltoid_moment_arms_agree_with_mobl_in_opensim(arm: MyoArm, elevation_deg: float) -> None:
    row = COORDINATES.index(ELEVATION)
    moment_arms_m = arm.muscle_state(math.radians(elevation_deg)).moment_arm_m[row]
    arms = dict(zip(ARM_MUSCLES, moment_arms_m, strict=True))
    for name, published_mm in MOBL_OPENSIM_MOMENT_ARMS_MM[elevation_deg].items():
        ours_mm = 1000.0 * arms[name]
        if name == "DELT2":
            assert 0.45 * published_mm < ours_mm < 0.85 * published_mm, ours_mm
        else:
            assert ours_mm == pytest.approx(published_mm, abs=MOMENT_ARM_TOLERANCE_MM), name
