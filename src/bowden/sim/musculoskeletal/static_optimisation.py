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
from bowden.sim.musculoskeletal._newton import newton_states

# Per Nm² of reserve torque: one Nm left to the reserve costs what 100 muscles at full activation do.
RESERVE_WEIGHT = 1.0e4
# Halvings of a Newton step before the batch solver gives a state up to the exact fallback (2⁻²⁰).
_HALVINGS = 20


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


def _bounded_least_squares(
    capacity: NDArray[np.float64], required: NDArray[np.float64], reserve_weight: float
) -> NDArray[np.float64]:
    """One state's activations as min |a|² + w|τ − A a|² over 0 ≤ a ≤ 1 (the reserve eliminated)."""
    muscles = capacity.shape[1]
    root = np.sqrt(reserve_weight)
    design = np.vstack([root * capacity, np.eye(muscles)])
    target = np.concatenate([root * required, np.zeros(muscles)])
    result = optimize.lsq_linear(design, target, bounds=(0.0, 1.0), method="bvls", tol=1e-14)
    return np.asarray(result.x)


def solve_static_batch(
    capacity_nm: NDArray[np.float64],
    required_nm: NDArray[np.float64],
    *,
    reserve_weight: float = RESERVE_WEIGHT,
    tolerance_nm: float = 1e-9,
    max_iterations: int = 20,
) -> StaticSolution:
    """:func:`solve_static` for many states at once (the batch path: a trial's every state).

    The same dual, maximised state by state by a compiled semismooth Newton method with
    backtracking (:func:`~bowden.sim.musculoskeletal._newton.newton_states`): the dual is piecewise
    quadratic, its Hessian on the current free set (muscles strictly between 0 and 1) is
    ``−(A_F A_Fᵀ/2 + I/(2w))``, and a full step is taken where it raises the dual, a halved one
    otherwise. Most states converge in a step or two from the previous state's answer (a trial's
states come in time order), the first from the all-free start. The few where it stalls
    (no step raises the dual) or that have not converged after ``max_iterations`` are solved one by
    one as the primal's bounded least squares (BVLS), exactly.

    Parameters
    ----------
    capacity_nm
        Shape (states, rows, muscles).
    required_nm
        Shape (states, rows).

    Returns
    -------
    Activations (states, muscles) and reserves (states, rows).
    """
    capacity = np.asarray(capacity_nm, dtype=np.float64)
    required = np.asarray(required_nm, dtype=np.float64)
    if capacity.ndim != 3 or required.shape != capacity.shape[:2]:
        raise ParameterError(
            f"capacity must be (states, rows, muscles) and required (states, rows), got "
            f"{capacity.shape} and {required.shape}"
        )
    if not (np.isfinite(capacity).all() and np.isfinite(required).all() and reserve_weight > 0):
        raise ParameterError("static optimisation needs finite torques and a positive reserve weight")
    capacity, required = np.ascontiguousarray(capacity), np.ascontiguousarray(required)
    multipliers = np.empty(capacity.shape[:2])
    activations = np.empty((capacity.shape[0], capacity.shape[2]))
    residual_nm = np.empty(capacity.shape[0])
    newton_states(capacity, required, multipliers, reserve_weight, tolerance_nm, max_iterations,
                  _HALVINGS, activations, residual_nm)
    # Newton can stall where the reserves carry part of the torque and few muscles are free (the
    # dual's curvature then spans 1/(2w) to |A|²): those few states are solved one by one as the
    # primal's bounded least squares (BVLS, exact in finitely many steps, about a millisecond).
    # (Within 10³ × the tolerance is converged: roundoff in the last steps.)
    for n in np.flatnonzero(residual_nm > 1e3 * tolerance_nm):
        activations[n] = _bounded_least_squares(capacity[n], required[n], reserve_weight)
        multipliers[n] = 2.0 * reserve_weight * (required[n] - capacity[n] @ activations[n])
    return StaticSolution(activations=activations, reserve_nm=multipliers / (2.0 * reserve_weight))
