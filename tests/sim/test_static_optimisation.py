"""Static optimisation against cases solved by hand (one joint, two muscles)."""

from __future__ import annotations

import numpy as np
import pytest

from bowden.errors import ParameterError
from bowden.sim.musculoskeletal.static_optimisation import solve_static


def test_two_agonists_share_the_torque_in_proportion_to_their_strength() -> None:
    # min a1² + a2² s.t. c1 a1 + c2 a2 = τ (Lagrange): a_i = τ c_i / (c1² + c2²).
    # c1 = 3 cm × 1000 N = 30 Nm, c2 = 2 cm × 500 N = 10 Nm, τ = 6 Nm: a = 6·(30, 10)/1000 = (0.18, 0.06).
    solution = solve_static(np.array([[30.0, 10.0]]), np.array([6.0]))
    np.testing.assert_allclose(solution.activations, [0.18, 0.06], atol=1e-6)
    assert abs(solution.reserve_nm[0]) < 1e-5


def test_an_antagonist_stays_silent_and_the_agonist_makes_it_alone() -> None:
    # Flexor 30 Nm, extensor −20 Nm at full activation; 5 Nm of extension needs the extensor at 0.25.
    solution = solve_static(np.array([[30.0, -20.0]]), np.array([-5.0]))
    np.testing.assert_allclose(solution.activations, [0.0, 0.25], atol=1e-6)


def test_what_the_muscles_cannot_make_is_left_to_the_reserve() -> None:
    solution = solve_static(np.array([[30.0, -20.0]]), np.array([50.0]))
    np.testing.assert_allclose(solution.activations, [1.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(solution.reserve_nm, [20.0], atol=1e-3)


def test_two_joints_a_two_joint_muscle_is_preferred() -> None:
    # Muscle 1 crosses both joints (10 Nm each), muscles 2 and 3 one each (10 Nm). τ = (2, 2) Nm:
    # minimise a1² + a2² + a3² with 10(a1 + a2) = 2 and 10(a1 + a3) = 2 → a2 = a3 = 0.2 − a1,
    # a1² + 2(0.2 − a1)² is least at a1 = 0.4/3.
    capacity = np.array([[10.0, 10.0, 0.0], [10.0, 0.0, 10.0]])
    solution = solve_static(capacity, np.array([2.0, 2.0]))
    a1 = 0.4 / 3.0
    np.testing.assert_allclose(solution.activations, [a1, 0.2 - a1, 0.2 - a1], atol=1e-6)


def test_shapes_that_do_not_fit_are_refused() -> None:
    with pytest.raises(ParameterError, match="coordinates"):
        solve_static(np.ones((2, 3)), np.ones(3))
