"""Compiled semismooth Newton on the static optimisation's dual, one state after another.

The batch path of :func:`~bowden.sim.musculoskeletal.static_optimisation.solve_static_batch`: a
trial's thousands of small problems (5 rows × 25 muscles) cost more in numpy's per-call overhead
than in arithmetic once only a few states are left iterating, so each state runs its own Newton
iteration and backtracking here, compiled (numba, cached on disk like the batch kernels), starting
from the previous state's answer where that fits better (states are given in time order).

For multipliers λ the dual's maximiser gives ``a = clip(Aᵀλ/2, 0, 1)``, reserves ``s = λ/(2w)``;
its gradient is the residual ``τ − A a − s`` and its Hessian on the free set F (0 < Aᵀλ/2 < 1) is
``−(A_F A_Fᵀ/2 + I/(2w))``. A step that does not raise the dual is halved up to ``halvings`` times;
a state whose step is halved away, or that has not converged in ``max_iterations``, keeps its
residual, which the caller compares (the exact fallback takes it).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from bowden.sim._kernels import jit


@jit
def _dual(
    capacity: NDArray[np.float64], required: NDArray[np.float64], multipliers: NDArray[np.float64],
    reserve_weight: float, activations: NDArray[np.float64], residual: NDArray[np.float64],
) -> float:
    """The dual's value at ``multipliers``; fills the activations and the residual."""
    rows, muscles = capacity.shape
    value = 0.0
    for i in range(muscles):
        drive = 0.0
        for k in range(rows):
            drive += capacity[k, i] * multipliers[k]
        a = min(max(drive / 2.0, 0.0), 1.0)
        activations[i] = a
        value += a * a
    for k in range(rows):
        made = 0.0
        for i in range(muscles):
            made += capacity[k, i] * activations[i]
        reserve = multipliers[k] / (2.0 * reserve_weight)
        residual[k] = required[k] - made - reserve
        value += reserve_weight * reserve * reserve + multipliers[k] * residual[k]
    return value


@jit
def newton_states(
    capacity: NDArray[np.float64], required: NDArray[np.float64], multipliers: NDArray[np.float64],
    reserve_weight: float, tolerance_nm: float, max_iterations: int, halvings: int,
    activations: NDArray[np.float64], residual_nm: NDArray[np.float64],
) -> None:
    """Maximise each state's dual from its ``multipliers`` (updated in place).

    Fills the activations and each state's largest remaining residual (Nm).
    """
    states, rows, muscles = capacity.shape
    residual = np.empty(rows)
    trial_residual = np.empty(rows)
    trial_activations = np.empty(muscles)
    hessian = np.empty((rows, rows))
    for n in range(states):
        cap, req, lam, act = capacity[n], required[n], multipliers[n], activations[n]
        value = _dual(cap, req, lam, reserve_weight, act, residual)
        # Consecutive states of a trial are close: the previous answer, where it fits better, starts
        # Newton on (nearly) the right free set, which the all-free start often is far from.
        if n > 0 and residual_nm[n - 1] <= tolerance_nm:
            warm = _dual(cap, req, multipliers[n - 1], reserve_weight, trial_activations, trial_residual)
            if np.max(np.abs(trial_residual)) < np.max(np.abs(residual)):
                lam[:] = multipliers[n - 1]
                act[:] = trial_activations
                residual[:] = trial_residual
                value = warm
        for _ in range(max_iterations):
            if np.max(np.abs(residual)) <= tolerance_nm:
                break
            for k in range(rows):
                for j in range(rows):
                    total = 0.0
                    for i in range(muscles):
                        drive = act[i]
                        if 0.0 < drive < 1.0:
                            total += cap[k, i] * cap[j, i]
                    hessian[k, j] = total / 2.0
                hessian[k, k] += 1.0 / (2.0 * reserve_weight)
            step = np.linalg.solve(hessian, residual)
            size = 1.0
            accepted = False
            for _halving in range(halvings):
                trial = lam + size * step
                new = _dual(cap, req, trial, reserve_weight, trial_activations, trial_residual)
                if new >= value - 1e-15 * max(1.0, abs(value)):
                    lam[:] = trial
                    act[:] = trial_activations
                    residual[:] = trial_residual
                    value = new
                    accepted = True
                    break
                size /= 2.0
            if not accepted:
                break
        residual_nm[n] = np.max(np.abs(residual))
