"""Compiled semismooth Newton on the static optimisation's dual, one state after another.

The batch path of :func:`~bowden.sim.musculoskeletal.static_optimisation.solve_static_batch`: a
trial's thousands of small problems (5 rows × 25 muscles) cost more in numpy's per-call overhead
than in arithmetic once only a few states are left iterating, so each state runs its own Newton
iteration and backtracking here, compiled (numba, cached on disk like the batch kernels), starting
from the previous state's answer (states are given in time order).

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
def _hessian(
    capacity: NDArray[np.float64], activations: NDArray[np.float64], reserve_weight: float,
    free_only: bool, out: NDArray[np.float64],
) -> None:
    """A_F A_Fᵀ/2 + I/(2w) over the free muscles (all muscles unless ``free_only``), symmetric."""
    rows, muscles = capacity.shape
    for k in range(rows):
        for j in range(k, rows):
            total = 0.0
            for i in range(muscles):
                if not free_only or 0.0 < activations[i] < 1.0:
                    total += capacity[k, i] * capacity[j, i]
            out[k, j] = total / 2.0
            out[j, k] = total / 2.0
        out[k, k] += 1.0 / (2.0 * reserve_weight)


@jit
def _solve_spd(matrix: NDArray[np.float64], rhs: NDArray[np.float64], out: NDArray[np.float64]) -> None:
    """``matrix⁻¹ rhs`` by Cholesky, in place of ``matrix`` (symmetric positive definite: the ridge
    1/(2w) keeps it so); LAPACK's general solver costs more than the arithmetic at 5 × 5."""
    rows = matrix.shape[0]
    for j in range(rows):
        diagonal = matrix[j, j]
        for p in range(j):
            diagonal -= matrix[j, p] * matrix[j, p]
        diagonal = np.sqrt(diagonal)
        matrix[j, j] = diagonal
        for i in range(j + 1, rows):
            total = matrix[i, j]
            for p in range(j):
                total -= matrix[i, p] * matrix[j, p]
            matrix[i, j] = total / diagonal
    for i in range(rows):  # L y = rhs
        total = rhs[i]
        for p in range(i):
            total -= matrix[i, p] * out[p]
        out[i] = total / matrix[i, i]
    for i in range(rows - 1, -1, -1):  # Lᵀ x = y
        total = out[i]
        for p in range(i + 1, rows):
            total -= matrix[p, i] * out[p]
        out[i] = total / matrix[i, i]


@jit
def _maximise(
    cap: NDArray[np.float64], req: NDArray[np.float64], lam: NDArray[np.float64],
    reserve_weight: float, tolerance_nm: float, max_iterations: int, halvings: int,
    act: NDArray[np.float64], scratch_act: NDArray[np.float64], residual: NDArray[np.float64],
    scratch_residual: NDArray[np.float64], hessian: NDArray[np.float64],
) -> float:
    """Newton from ``lam`` (updated in place, with ``act``); returns the largest residual, Nm."""
    value = _dual(cap, req, lam, reserve_weight, act, residual)
    step = np.empty(len(lam))
    trial = np.empty(len(lam))
    for _ in range(max_iterations):
        if np.max(np.abs(residual)) <= tolerance_nm:
            break
        _hessian(cap, act, reserve_weight, True, hessian)
        _solve_spd(hessian, residual, step)
        size = 1.0
        accepted = False
        for _halving in range(halvings):
            for k in range(len(lam)):
                trial[k] = lam[k] + size * step[k]
            new = _dual(cap, req, trial, reserve_weight, scratch_act, scratch_residual)
            if new >= value - 1e-15 * max(1.0, abs(value)):
                lam[:] = trial
                act[:] = scratch_act
                residual[:] = scratch_residual
                value = new
                accepted = True
                break
            size /= 2.0
        if not accepted:
            break
    return float(np.max(np.abs(residual)))


@jit
def newton_states(
    capacity: NDArray[np.float64], required: NDArray[np.float64], multipliers: NDArray[np.float64],
    reserve_weight: float, tolerance_nm: float, max_iterations: int, halvings: int,
    activations: NDArray[np.float64], residual_nm: NDArray[np.float64],
) -> None:
    """Maximise each state's dual; fill ``multipliers``, activations and the largest residual (Nm).

    A state starts from the previous state's answer when that converged (consecutive states of a
    trial are close, so Newton starts on nearly the right free set); where that does not converge,
    or there is none, from the all-free multipliers ``(A Aᵀ/2 + I/(2w))⁻¹ τ``.
    """
    states, rows, muscles = capacity.shape
    residual = np.empty(rows)
    scratch_residual = np.empty(rows)
    scratch_act = np.empty(muscles)
    hessian = np.empty((rows, rows))
    for n in range(states):
        cap, req, lam, act = capacity[n], required[n], multipliers[n], activations[n]
        left = np.inf
        if n > 0 and residual_nm[n - 1] <= tolerance_nm:
            lam[:] = multipliers[n - 1]
            left = _maximise(cap, req, lam, reserve_weight, tolerance_nm, max_iterations, halvings,
                             act, scratch_act, residual, scratch_residual, hessian)
        if left > tolerance_nm:
            _hessian(cap, act, reserve_weight, False, hessian)
            _solve_spd(hessian, req, lam)
            left = _maximise(cap, req, lam, reserve_weight, tolerance_nm, max_iterations, halvings,
                             act, scratch_act, residual, scratch_residual, hessian)
        residual_nm[n] = left
