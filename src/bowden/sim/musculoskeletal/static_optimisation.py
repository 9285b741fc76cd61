"""Static optimisation: the activations that make the required joint torques at least effort.

At each instant, find activations a ∈ [0, 1] of the muscles with

    minimise Σ a_i² + w Σ s_k²   subject to   A a + s = τ,

where ``A[k, i]`` is the torque muscle i makes about coordinate k at full activation (moment arm ×
its force at that length and velocity), ``τ`` the torque the muscles must supply and ``s`` reserve
torques, heavily weighted (w), that take up what the muscles cannot make (OpenSim's reserve
actuators; Crowninshield & Brand 1981, J Biomech 14:793 for the sum of squared activations as the
criterion of least effort; Anderson & Pandy 2001, J Biomech 34:153 for its agreement with dynamic
optimisation in gait).

The problem is a strictly convex quadratic programme with box bounds; it is solved through its
dual, which has only one variable per coordinate: for multipliers λ the minimising activations are
``a = clip(Aᵀλ / 2, 0, 1)`` and reserves ``s = λ / (2w)``, and the dual is concave and
differentiable with gradient ``τ − A a − s``. SciPy's BFGS maximises it; the answer is the
primal minimiser (strong duality holds: the constraints are linear and always feasible with the
reserves).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import optimize

from bowden.errors import ParameterError

# Per Nm² of reserve torque: one Nm left to the reserve costs what 100 muscles at full activation do.
RESERVE_WEIGHT = 1.0e4


@dataclass(frozen=True)
class StaticSolution:
    """Activations (one per muscle) and the reserve torques (one per coordinate, Nm) left unmade."""

    activations: NDArray[np.float64]
    reserve_nm: NDArray[np.float64]


def _primal(
    capacity: NDArray[np.float64], multipliers: NDArray[np.float64], reserve_weight: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    activations = np.clip(capacity.T @ multipliers / 2.0, 0.0, 1.0)
    return activations, multipliers / (2.0 * reserve_weight)


def solve_static(
    capacity_nm: NDArray[np.float64],
    required_nm: NDArray[np.float64],
    *,
    reserve_weight: float = RESERVE_WEIGHT,
) -> StaticSolution:
    """Activations of least Σ a² that make ``required_nm`` with the muscles' ``capacity_nm``.

    Parameters
    ----------
    capacity_nm
        Shape (coordinates, muscles): torque of each muscle about each coordinate at full
        activation, Nm (positive along the coordinate).
    required_nm
        Shape (coordinates,): the torque the muscles must make, Nm.
    reserve_weight
        Cost of a reserve torque per Nm² (relative to an activation's square).
    """
    capacity = np.atleast_2d(np.asarray(capacity_nm, dtype=np.float64))
    required = np.atleast_1d(np.asarray(required_nm, dtype=np.float64))
    if capacity.ndim != 2 or required.shape != (capacity.shape[0],):
        raise ParameterError(
            f"capacity must be (coordinates, muscles) and required (coordinates,), got "
            f"{capacity.shape} and {required.shape}"
        )
    if not (np.isfinite(capacity).all() and np.isfinite(required).all() and reserve_weight > 0):
        raise ParameterError("static optimisation needs finite torques and a positive reserve weight")

    def negative_dual(multipliers: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        a, s = _primal(capacity, multipliers, reserve_weight)
        residual = required - capacity @ a - s
        value = a @ a + reserve_weight * (s @ s) + multipliers @ residual
        return -float(value), -residual

    # The dual's curvature is that of A Aᵀ/2: scale the start so BFGS begins near the answer.
    gram = capacity @ capacity.T / 2.0 + np.eye(len(required)) / (2.0 * reserve_weight)
    start = np.linalg.solve(gram, required)
    result = optimize.minimize(negative_dual, start, jac=True, method="BFGS",
                               options={"gtol": 1e-10, "maxiter": 500})
    activations, reserve = _primal(capacity, result.x, reserve_weight)
    return StaticSolution(activations=activations, reserve_nm=reserve)
