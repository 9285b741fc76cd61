"""MyoArm's mechanics tabulated over the states the trials visit, cached on disk (issue 30, item 3).

Static optimisation needs, at each state of a trial, every muscle's torque capacity and the torques
the muscles must make. Both come from MuJoCo and cost about a millisecond a state; a study visits
millions. They are smooth in the state, and the required torque is linear in the acceleration, the
hand load and the cable's tension, so the table holds, on a grid of elevation θ × velocity θ̇:

- ``capacity`` (θ, θ̇, coordinates, muscles): moment arm × active force at full activation, Nm;
- ``passive`` (θ, θ̇, coordinates): the passive muscle forces' torques, Nm;
- ``arm`` (θ, θ̇, coordinates): the arm's own gravity and velocity torques (no load, no cable), Nm;
- ``arm_mass_kg``: MyoArm's arm (humerus to hand), for scaling to a participant, and the muscles'
  ``max_force_n``;

and on θ alone the torque per unit of acceleration (``inertia``, Nm per rad/s²), of hand load
(``hand``, Nm per kg) and of cable tension (``cable``, Nm per N). Evaluation interpolates
(:func:`interpolate`); a trial's states are then solved together
(:func:`~bowden.sim.musculoskeletal.static_optimisation.solve_static_batch`).

The table is MyoArm's, computed once (≈ 2–4 s) and kept in ``__pycache__`` beside this module,
like numba's compiled kernels, under a digest of the sources, MuJoCo's and myo-sim's versions and
the grid; a participant scales it (:mod:`~bowden.sim.musculoskeletal.trial`).
"""

from __future__ import annotations

import functools
import hashlib
import os
import tempfile
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from bowden.errors import ParameterError
from bowden.model import CuffGeometry
from bowden.sim._kernels import jit

ELEVATION_GRID_RAD = np.radians(np.arange(-10.0, 150.0 + 1e-9, 2.5))
VELOCITY_GRID_RAD_S = np.arange(-6.0, 6.0 + 1e-9, 0.5)
_FIELDS = ("capacity", "passive", "arm", "inertia", "hand", "cable", "arm_mass_kg", "max_force_n")


@dataclass(frozen=True)
class MechanicsTable:
    """MyoArm's mechanics on the grid (see the module's docstring)."""

    elevation_rad: NDArray[np.float64]
    velocity_rad_s: NDArray[np.float64]
    capacity: NDArray[np.float64]
    passive: NDArray[np.float64]
    arm: NDArray[np.float64]
    inertia: NDArray[np.float64]
    hand: NDArray[np.float64]
    cable: NDArray[np.float64]
    arm_mass_kg: NDArray[np.float64]  # 0-d: MyoArm's humerus, forearm and hand, kg
    max_force_n: NDArray[np.float64]  # the muscles' maximal isometric forces, N


# The sources as they were imported, not as they are on disk when the digest is taken: a process that
# imported an older myoarm.py must not file its table under the digest of a newer one (it did once,
# when the file was edited while a study ran).
_SOURCES = tuple(
    (Path(__file__).parent / name).read_bytes() for name in ("table.py", "myoarm.py")
)


def _digest() -> str:
    h = hashlib.sha256()
    for source in _SOURCES:
        h.update(source)
    for package in ("mujoco", "myo-sim"):
        try:
            h.update(metadata.version(package).encode())
        except metadata.PackageNotFoundError:
            raise ParameterError(
                f"the musculoskeletal participants need {package}: pip install 'bowden[msk]'"
            ) from None
    h.update(ELEVATION_GRID_RAD.tobytes() + VELOCITY_GRID_RAD_S.tobytes())
    h.update(repr(CuffGeometry()).encode())
    return h.hexdigest()[:16]


def cache_path() -> Path:
    """Where the table is kept: ``__pycache__`` beside this module, named by its digest."""
    return Path(__file__).parent / "__pycache__" / f"myoarm_table-{_digest()}.npz"


def compute_table() -> MechanicsTable:
    """Evaluate MyoArm on the grid (the cold path)."""
    from bowden.sim.musculoskeletal.myoarm import MyoArm

    arm = MyoArm()
    geometry = CuffGeometry()
    n_el, n_vel = len(ELEVATION_GRID_RAD), len(VELOCITY_GRID_RAD_S)
    probe = arm.muscle_state(0.0)
    n_coord, n_muscle = probe.moment_arm_m.shape
    capacity = np.empty((n_el, n_vel, n_coord, n_muscle))
    passive = np.empty((n_el, n_vel, n_coord))
    own = np.empty((n_el, n_vel, n_coord))
    inertia, hand, cable = (np.empty((n_el, n_coord)) for _ in range(3))
    for i, theta in enumerate(ELEVATION_GRID_RAD):
        for j, velocity in enumerate(VELOCITY_GRID_RAD_S):
            state = arm.muscle_state(theta, velocity)
            capacity[i, j] = state.moment_arm_m * state.active_force_n[None, :]
            passive[i, j] = state.moment_arm_m @ state.passive_force_n
            own[i, j] = arm.required_torques_nm(theta, velocity, 0.0, hand_load_kg=0.0)
        still = own[i, VELOCITY_GRID_RAD_S.searchsorted(0.0)]
        inertia[i] = arm.required_torques_nm(theta, 0.0, 1.0, hand_load_kg=0.0) - still
        hand[i] = arm.required_torques_nm(theta, 0.0, 0.0, hand_load_kg=1.0) - still
        cable[i] = arm.required_torques_nm(
            theta, 0.0, 0.0, hand_load_kg=0.0, cable_tension_n=1.0, geometry=geometry
        ) - still
    arm_mass_kg = np.array(arm.model.body_subtreemass[arm.model.body("humerus_r").id])
    return MechanicsTable(ELEVATION_GRID_RAD.copy(), VELOCITY_GRID_RAD_S.copy(), capacity, passive, own,
                          inertia, hand, cable, arm_mass_kg,
                          arm.max_force_n)


@functools.lru_cache(maxsize=1)
def load_table() -> MechanicsTable:
    """The table: from the cache if it is there and current, else computed and cached."""
    path = cache_path()
    if path.exists():
        with np.load(path) as stored:
            return MechanicsTable(ELEVATION_GRID_RAD.copy(), VELOCITY_GRID_RAD_S.copy(),
                                  *(np.asarray(stored[f]) for f in _FIELDS))
    table = compute_table()
    path.parent.mkdir(parents=True, exist_ok=True)
    # Written whole and renamed: worker processes may compute it at the same time.
    handle, temporary = tempfile.mkstemp(dir=path.parent, suffix=".npz")
    with os.fdopen(handle, "wb") as out:
        np.savez(out, **{f: getattr(table, f) for f in _FIELDS})
    os.replace(temporary, path)
    return table


def _bracket(
    grid: NDArray[np.float64], x: NDArray[np.float64]
) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Lower grid index and weight of the upper neighbour; outside the grid, its edge."""
    clipped = np.clip(x, grid[0], grid[-1])
    index = np.clip(np.searchsorted(grid, clipped, side="right") - 1, 0, len(grid) - 2)
    weight = (clipped - grid[index]) / (grid[index + 1] - grid[index])
    return index, weight


@jit
def _bilinear(
    grid: NDArray[np.float64], i: NDArray[np.intp], j: NDArray[np.intp], u: NDArray[np.float64],
    v: NDArray[np.float64], out: NDArray[np.float64],
) -> None:
    """``out[n] = `` the (θ, θ̇) grid's values (flattened after the two grid axes) at each state."""
    for n in range(len(i)):
        a, b = i[n], j[n]
        w00, w10 = (1.0 - u[n]) * (1.0 - v[n]), u[n] * (1.0 - v[n])
        w01, w11 = (1.0 - u[n]) * v[n], u[n] * v[n]
        for f in range(out.shape[1]):
            out[n, f] = (w00 * grid[a, b, f] + w10 * grid[a + 1, b, f] + w01 * grid[a, b + 1, f]
                         + w11 * grid[a + 1, b + 1, f])


def interpolate(
    table: MechanicsTable, elevation_rad: NDArray[np.float64], velocity_rad_s: NDArray[np.float64]
) -> dict[str, NDArray[np.float64]]:
    """Every field at these states: bilinear in (θ, θ̇), linear in θ for the θ-only fields."""
    i, u = _bracket(table.elevation_rad, np.asarray(elevation_rad, dtype=np.float64))
    j, v = _bracket(table.velocity_rad_s, np.asarray(velocity_rad_s, dtype=np.float64))
    out: dict[str, NDArray[np.float64]] = {}
    for name in ("capacity", "passive", "arm"):
        grid = getattr(table, name)
        flat = np.ascontiguousarray(grid.reshape(grid.shape[0], grid.shape[1], -1))
        values = np.empty((len(i), flat.shape[2]))
        _bilinear(flat, i, j, u, v, values)  # compiled: numpy's four gathers cost 5 ms a trial
        out[name] = values.reshape((len(i), *grid.shape[2:]))
    for name in ("inertia", "hand", "cable"):
        grid = getattr(table, name)
        out[name] = (1 - u)[:, None] * grid[i] + u[:, None] * grid[i + 1]
    return out


def grid_size() -> int:
    """States in the (θ, θ̇) grid."""
    return len(ELEVATION_GRID_RAD) * len(VELOCITY_GRID_RAD_S)


__all__ = ["MechanicsTable", "cache_path", "compute_table", "grid_size", "interpolate", "load_table"]
