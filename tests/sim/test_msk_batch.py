"""The musculoskeletal batch path: many states solved at once, the co-contraction row, the table."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bowden.sim.musculoskeletal.static_optimisation import solve_static, solve_static_batch


def test_batch_solver_equals_the_single_state_solver() -> None:
    # Random problems, many with saturated muscles and reserves: the batched semismooth Newton
    # must find the same minimiser as BFGS on each one's dual. (40 of them: 9 saturate a muscle and
    # 31 need a reserve; the single-state solver takes most of the test's time.)
    rng = np.random.default_rng(3)
    capacity = rng.normal(0.0, 20.0, (40, 5, 25))
    required = rng.normal(0.0, 30.0, (40, 5))
    batch = solve_static_batch(capacity, required)
    assert (batch.activations > 1.0 - 1e-9).any(axis=1).sum() >= 5
    assert (np.abs(batch.reserve_nm) > 1e-6).any(axis=1).sum() >= 20
    for n in range(len(required)):
        single = solve_static(capacity[n], required[n])
        assert batch.activations[n] == pytest.approx(single.activations, abs=5e-5)
        assert batch.reserve_nm[n] == pytest.approx(single.reserve_nm, abs=5e-5)


def test_batch_solver_hand_solved_sharing() -> None:
    # One joint, two agonists of 10 and 20 Nm: least Σa² with 6 Nm gives a ∝ capacity,
    # a = 6·c/(10² + 20²) → 0.12 and 0.24 (as tests/sim/test_static_optimisation.py derives).
    solution = solve_static_batch(np.array([[[10.0, 20.0]]]), np.array([[6.0]]))
    assert solution.activations[0] == pytest.approx([0.12, 0.24], abs=1e-6)


pytest.importorskip("mujoco")
pytest.importorskip("myo_sim")

from bowden.sim.musculoskeletal.myoarm import ARM_MUSCLES, COORDINATES, ELEVATION, recruitable  # noqa: E402
from bowden.sim.musculoskeletal.table import load_table  # noqa: E402
from bowden.sim.musculoskeletal.trial import required_and_capacity  # noqa: E402
from bowden.sim.participants import generate_cohort  # noqa: E402


@pytest.mark.parametrize("cable_n", [0.0, 40.0])
def test_cocontraction_activates_the_posterior_deltoid_and_keeps_the_net_torque(cable_n: float) -> None:
    participant = generate_cohort(0, muscles="musculoskeletal")[0]
    table = load_table()
    theta = np.array([math.radians(60.0)] * 3)
    zero = np.zeros(3)
    capacity, required = required_and_capacity(
        table, participant, theta, zero, zero, np.full(3, cable_n), np.array([0.0, 0.5, 2.5])
    )
    solution = solve_static_batch(capacity, required)
    delt3 = ARM_MUSCLES.index("DELT3")
    # Least Σa² alone leaves the antagonist silent; 2 Nm more co-contraction recruits it. (Without the
    # biceps' long head the plane of elevation needs ≈ 0.3 Nm from the extensors at 60°, so below that
    # the row cannot hold exactly: the states compared start from 0.5 Nm.)
    assert solution.activations[0, delt3] < 1e-6
    assert solution.activations[2, delt3] > solution.activations[1, delt3] + 0.005
    row = COORDINATES.index(ELEVATION)
    net = np.einsum("nm,nm->n", capacity[:, row, :], solution.activations)
    # The net elevation torque is what the arm needs either way (the flexors add what the extensors take).
    assert net[2] == pytest.approx(net[1], abs=1e-3)
    assert np.abs(solution.reserve_nm[1:, :2]).max() < 1e-3


def test_the_long_head_of_the_biceps_is_not_recruited() -> None:
    # Levy et al. 2001: no EMG activity of the biceps' long head in shoulder motion with the elbow
    # held extended. Its capacity column is zero, every other muscle's is unchanged, and least Σa²
    # leaves it at exactly zero while the arm is held at 60° (before, MoBL's 6.5 mm flexion moment
    # arm gave it a share of the elevation torque).
    participant = generate_cohort(0, muscles="musculoskeletal")[0]
    table = load_table()
    theta = np.array([math.radians(60.0)])
    zero = np.zeros(1)
    capacity, required = required_and_capacity(table, participant, theta, zero, zero, zero, np.array([0.5]))
    biceps = ARM_MUSCLES.index("BIClong")
    raw = recruitable(np.ones((2, len(ARM_MUSCLES))))
    assert raw[:, biceps].tolist() == [0.0, 0.0]
    assert np.delete(raw, biceps, axis=1).min() == 1.0
    assert np.all(capacity[..., biceps] == 0.0)
    assert np.abs(capacity[0, COORDINATES.index(ELEVATION), ARM_MUSCLES.index("BICshort")]) > 0.0
    solution = solve_static_batch(capacity, required)
    assert solution.activations[0, biceps] == 0.0
    assert solution.activations[0, ARM_MUSCLES.index("DELT1")] > 0.05


def test_the_cable_lowers_the_anterior_deltoid_through_the_table() -> None:
    participant = generate_cohort(0, muscles="musculoskeletal")[0]
    theta = np.array([math.radians(60.0)] * 2)
    zero = np.zeros(2)
    capacity, required = required_and_capacity(
        load_table(), participant, theta, zero, zero, np.array([0.0, 50.0]), zero
    )
    delt1 = solve_static_batch(capacity, required).activations[:, ARM_MUSCLES.index("DELT1")]
    assert delt1[1] < 0.8 * delt1[0]


def test_the_exact_fallback_gives_the_single_state_answer() -> None:
    # No Newton step allowed: every state goes to the bounded least squares (BVLS), which must find
    # the minimiser that BFGS on the dual finds, saturated muscles and reserves included.
    rng = np.random.default_rng(11)
    capacity = rng.normal(0.0, 20.0, (30, 5, 25))
    required = rng.normal(0.0, 60.0, (30, 5))
    fallback = solve_static_batch(capacity, required, max_iterations=0)
    for n in range(len(required)):
        single = solve_static(capacity[n], required[n])
        assert fallback.activations[n] == pytest.approx(single.activations, abs=5e-5)
        assert fallback.reserve_nm[n] == pytest.approx(single.reserve_nm, abs=5e-5)


def test_time_ordered_states_start_from_their_neighbour_and_keep_the_answer() -> None:
    # A smooth path through problem space (as a trial's states are): the warm start must not change
    # any state's minimiser.
    rng = np.random.default_rng(5)
    ends = rng.normal(0.0, 20.0, (2, 5, 25)), rng.normal(0.0, 30.0, (2, 5))
    s = np.linspace(0.0, 1.0, 200)
    capacity = (1 - s)[:, None, None] * ends[0][0] + s[:, None, None] * ends[0][1]
    required = (1 - s)[:, None] * ends[1][0] + s[:, None] * ends[1][1]
    batch = solve_static_batch(capacity, required)
    for n in range(0, len(required), 7):
        single = solve_static(capacity[n], required[n])
        assert batch.activations[n] == pytest.approx(single.activations, abs=5e-5)


def test_the_table_gives_the_direct_mujoco_solve_between_its_grid_points() -> None:
    # A participant the table does not scale (MyoArm's own arm mass, unit gravity and inertia
    # scales): the interpolated mechanics, solved, against MuJoCo and the single-state solve at states
    # off the grid (2.5° × 0.5 rad/s). Tolerance 0.002 in activation (bilinear interpolation's error
    # was at most 0.0004 at these states, activations up to 0.85).
    from dataclasses import replace

    from bowden.model import CuffGeometry
    from bowden.sim.musculoskeletal.activations import solve_state
    from bowden.sim.musculoskeletal.myoarm import MyoArm
    from bowden.sim.musculoskeletal.trial import DE_LEVA_ARM_FRACTION

    table = load_table()
    base = generate_cohort(0, muscles="musculoskeletal")[0]
    subject = replace(base.subject, mass_kg=float(table.arm_mass_kg) / DE_LEVA_ARM_FRACTION)
    participant = replace(base, subject=subject, gravity_scale=1.0, inertia_scale=1.0, hand_load_kg=0.5)
    states = np.array([[21.3, 0.8, 3.0, 10.0], [47.9, -1.3, -6.0, 35.0], [88.1, 2.2, 1.5, 55.0],
                       [109.6, -0.3, 0.0, 0.0]])
    theta, velocity, acceleration, tension = np.radians(states[:, 0]), *states[:, 1:].T
    capacity, required = required_and_capacity(
        table, participant, theta, velocity, acceleration, tension, np.zeros(len(states))
    )
    rows = len(COORDINATES)  # without the co-contraction row, which solve_state does not have
    tabled = solve_static_batch(capacity[:, :rows], required[:, :rows])
    arm = MyoArm()
    for n in range(len(states)):
        direct = solve_state(arm, theta[n], velocity[n], acceleration[n], hand_load_kg=0.5,
                             cable_tension_n=tension[n], geometry=CuffGeometry())
        assert tabled.activations[n] == pytest.approx(direct.activations, abs=2e-3)


def test_the_table_digest_is_that_of_the_imported_sources_not_of_the_files_on_disk(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # A study's process computed a table with the myoarm.py it had imported and filed it under the
    # digest of the file edited since: the digest must not follow the file on disk.
    from bowden.sim.musculoskeletal import table

    before = table._digest()
    monkeypatch.setattr(table.Path, "read_bytes", lambda self: b"edited since the import")
    assert table._digest() == before
