"""The one electrode mapping of the musculoskeletal participants (single state and study path alike)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bowden.contracts import MUSCLES

pytest.importorskip("mujoco")
pytest.importorskip("myo_sim")

from bowden.sim.musculoskeletal.activations import electrode_activations, solve_state
from bowden.sim.musculoskeletal.myoarm import ARM_MUSCLES, MyoArm


def test_each_electrode_reads_its_muscles_and_the_trapezius_is_the_deltoid_proxy() -> None:
    # Hand-made activations: each muscle its own value, LAT1-3 with forces 1:2:1 -> weights 1/4, 1/2, 1/4.
    activations = np.linspace(0.01, 0.25, len(ARM_MUSCLES))
    force = np.full(len(ARM_MUSCLES), 500.0)
    lat = [ARM_MUSCLES.index(n) for n in ("LAT1", "LAT2", "LAT3")]
    force[lat] = [100.0, 200.0, 100.0]
    out = electrode_activations(activations, force)
    a = dict(zip(ARM_MUSCLES, activations, strict=True))
    expected = {
        "anterior_deltoid": a["DELT1"], "medial_deltoid": a["DELT2"], "posterior_deltoid": a["DELT3"],
        "biceps": a["BIClong"], "triceps": a["TRIlong"], "pectoralis_major": a["PECM1"],
        "latissimus_dorsi": 0.25 * a["LAT1"] + 0.5 * a["LAT2"] + 0.25 * a["LAT3"],
        "trapezius": 0.5 * (a["DELT1"] + a["DELT2"]),  # unweighted, whatever the deltoids' forces
    }
    assert out == pytest.approx([expected[m] for m in MUSCLES], abs=1e-12)
    # Many states at once give each state's row.
    many = electrode_activations(np.stack([activations, 2 * activations]), force)
    assert many[1] == pytest.approx(2 * out, abs=1e-12)


def test_the_single_state_path_gives_the_trapezius_proxy() -> None:
    arm = MyoArm()
    solution = solve_state(arm, math.radians(60.0), 0.0, 0.0, hand_load_kg=0.5)
    electrodes = electrode_activations(solution.activations, arm.max_force_n)
    assert np.isfinite(electrodes).all()
    delt1, delt2 = (solution.activations[ARM_MUSCLES.index(n)] for n in ("DELT1", "DELT2"))
    assert electrodes[MUSCLES.index("trapezius")] == pytest.approx(0.5 * (delt1 + delt2))
