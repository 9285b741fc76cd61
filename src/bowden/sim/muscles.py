"""Muscle activations of the eight recorded shoulder muscles from the torque the arm needs.

The shoulder torque the participant plans (elevation > 0) is shared among agonists of forward
elevation (anterior and medial deltoid, trapezius, clavicular pectoralis major, biceps long head) and
antagonists (posterior deltoid, latissimus dorsi, triceps long head) as the paper groups them
(Protocol); its corrections against forces it did not plan for are made by the muscles that oppose
those forces, and its co-contraction by both groups (see :func:`muscle_activations`). Eccentric
work (lowering against gravity) needs less activation for the same torque (Enoka 1996, J Appl
Physiol 81:2339: ≈ 30 % less); the trapezius is recruited more as the arm rises (scapular upward
rotation, Inman et al. 1944); co-contraction grows with movement speed. Activation follows
excitation with first-order dynamics, faster to rise than to fall (Zajac 1989: ≈ 15/50 ms).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from bowden.contracts import MUSCLES
from bowden.errors import ParameterError
from bowden.sim._kernels import jit

# Share of the normalised elevation torque each muscle carries (agonist, antagonist), the resting
# activation and the co-contraction weight. Order of contracts.MUSCLES.
_AGONIST = np.array([1.00, 0.70, 0.05, 0.25, 0.02, 0.60, 0.03, 0.50])
_ANTAGONIST = np.array([0.02, 0.10, 1.00, 0.02, 0.45, 0.05, 0.85, 0.05])
_REST = np.array([0.010, 0.010, 0.010, 0.020, 0.015, 0.020, 0.010, 0.010])
_COCONTRACTION = np.array([0.6, 0.5, 0.6, 0.8, 0.8, 0.5, 0.5, 0.4])
# Elbow held extended with a load in the hand: biceps and triceps stabilise in proportion to sin θ.
_ELBOW_HOLD = np.array([0.0, 0.0, 0.0, 0.08, 0.05, 0.0, 0.0, 0.0])
_TRAPEZIUS = MUSCLES.index("trapezius")
ECCENTRIC_REDUCTION = 0.3
ACTIVATION_TIME_S = 0.015
DEACTIVATION_TIME_S = 0.050


def max_elevation_torque_nm(mass_kg: float) -> float:
    """Maximal voluntary shoulder-flexion torque, ≈ 0.7 Nm per kg body mass (adults, isometric at 90°)."""
    return 0.7 * mass_kg


@jit
def _activation_dynamics(
    excitation: NDArray[np.float64], dt: float, rise_s: float, fall_s: float
) -> NDArray[np.float64]:
    out = np.empty_like(excitation)
    a_rise = 1.0 - math.exp(-dt / rise_s)
    a_fall = 1.0 - math.exp(-dt / fall_s)
    for m in range(excitation.shape[1]):
        a = excitation[0, m]
        for i in range(excitation.shape[0]):
            u = excitation[i, m]
            a += (u - a) * (a_rise if u > a else a_fall)
            out[i, m] = a
    return out


def activation_dynamics(
    excitation: NDArray[np.float64], dt: float, rise_s: float, fall_s: float
) -> NDArray[np.float64]:
    """First-order activation from excitation (samples, muscles), faster to rise than to fall."""
    return _activation_dynamics(np.ascontiguousarray(excitation, dtype=np.float64), dt, rise_s, fall_s)


def muscle_activations(
    shoulder_torque_nm: NDArray[np.float64],
    elevation_rad: NDArray[np.float64],
    elevation_velocity_rad_s: NDArray[np.float64],
    *,
    sample_rate_hz: float,
    max_torque_nm: float,
    correction_torque_nm: NDArray[np.float64] | None = None,
    cocontraction_nm: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Activations (0–1), shape (n, 8) in the order of ``contracts.MUSCLES``.

    Parameters
    ----------
    shoulder_torque_nm
        Net muscle torque about the shoulder (> 0 elevates), Nm, sampled at ``sample_rate_hz``.
    elevation_rad, elevation_velocity_rad_s
        The arm's elevation and velocity at the same samples.
    max_torque_nm
        The participant's maximal elevation torque (normalises the torque).
    correction_torque_nm
        The part of the net torque that counters forces the participant did not plan for (None:
        none): its feedback about the intended movement and what it has learned of the suit. It is
        made by the muscles that act against those forces — a downward correction by the extensors
        even while the flexors hold the arm up — not by relaxing the planned torque's muscles:
        stretch responses come from the stretched muscle (Pruszynski & Scott 2012, Exp Brain Res
        218:341), and a learned force field is countered by the muscles opposing it (Thoroughman &
        Shadmehr 1999, J Neurosci 19:8573).
    cocontraction_nm
        Torque each side of the joint adds to stiffen it (None: none); it activates agonists and
        antagonists alike and cancels in the net torque.
    """
    torque = np.asarray(shoulder_torque_nm, dtype=np.float64)
    if torque.ndim != 1 or torque.shape != np.shape(elevation_rad) or torque.shape != np.shape(
        elevation_velocity_rad_s
    ):
        raise ParameterError("shoulder torque, elevation and velocity must be 1-D arrays of one length")
    if not (sample_rate_hz > 0 and max_torque_nm > 0):
        raise ParameterError("sample_rate_hz and max_torque_nm must be positive")
    th = np.asarray(elevation_rad, dtype=np.float64)
    thd = np.asarray(elevation_velocity_rad_s, dtype=np.float64)
    correction = _optional_signal(correction_torque_nm, torque.shape, "correction_torque_nm")
    stiffening = _optional_signal(cocontraction_nm, torque.shape, "cocontraction_nm")
    planned = torque - correction
    # Less activation for the same torque while the muscle lengthens (lowering under load).
    eccentric = 1.0 - ECCENTRIC_REDUCTION * np.tanh(np.maximum(-thd, 0.0) / 0.5)
    lifting = np.maximum(planned, 0.0) * eccentric + np.maximum(correction, 0.0) + stiffening
    pulling_down = np.maximum(-planned, 0.0) + np.maximum(-correction, 0.0) + stiffening
    lifting = np.clip(lifting / max_torque_nm, 0.0, 1.0)
    pulling_down = np.clip(pulling_down / max_torque_nm, 0.0, 1.0)
    speed_cocontraction = 0.01 + 0.012 * np.abs(thd)
    excitation = (
        _REST[None, :]
        + _AGONIST[None, :] * lifting[:, None]
        + _ANTAGONIST[None, :] * pulling_down[:, None]
        + _COCONTRACTION[None, :] * speed_cocontraction[:, None]
        + _ELBOW_HOLD[None, :] * np.clip(np.sin(th), 0.0, 1.0)[:, None]
    )
    upward_rotation = 0.6 + 0.8 * np.clip(th / (0.5 * math.pi), 0.0, 1.5)
    excitation[:, _TRAPEZIUS] *= upward_rotation
    excitation = np.clip(excitation, 0.0, 1.0)
    return _activation_dynamics(
        np.ascontiguousarray(excitation), 1.0 / sample_rate_hz, ACTIVATION_TIME_S, DEACTIVATION_TIME_S
    )


def _optional_signal(
    values: NDArray[np.float64] | None, shape: tuple[int, ...], name: str
) -> NDArray[np.float64]:
    if values is None:
        return np.zeros(shape)
    array = np.asarray(values, dtype=np.float64)
    if array.shape != shape:
        raise ParameterError(f"{name} must have the shoulder torque's shape {shape}, got {array.shape}")
    return array
