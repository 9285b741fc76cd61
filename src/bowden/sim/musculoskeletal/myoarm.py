"""The MyoArm musculoskeletal model (MuJoCo): posture, muscle geometry and inverse dynamics.

MyoArm (the ``myo-sim`` package, Apache-2.0) is the MuJoCo translation of the MoBL upper-extremity
model (Holzbaur, Murray & Delp 2005, Ann Biomed Eng 33:829; Saul et al. 2015, Comput Methods
Biomech Biomed Engin 18:1445): 38 degrees of freedom and 63 Hill-type muscles. Its shoulder girdle
follows the humerus through linear equality constraints (the scapulohumeral rhythm of de Groot &
Brand 2001): every clavicle and scapula coordinate is a fixed multiple of ``shoulder_elv_r``, and
``shoulder1_r2_r`` is minus ``elv_angle_r``. A coordinate is therefore a direction in joint space
(:meth:`MyoArm.coupling`), and a muscle's moment arm about it is the derivative of its length along
that direction, with all coupled joints moving — as OpenSim computes moment arms of coupled
coordinates.

The virtual participants elevate the humerus in the plane of forward flexion (``elv_angle_r`` = 90°,
the paper's "forward humeral elevation") with the elbow extended and a 0.5 kg load in the hand; the
suit's cable pulls the humerus at the upper-arm cuff toward the cable exit on the shoulder cuff
(:class:`bowden.model.CuffGeometry`, the geometry the controller assumes).

**Where the cable's exit rides.** The paper's exit is "secured above the shoulder" by a 3D-printed
shoulder cuff (Methods; its Fig. 1C) that rests on the shoulder, so it moves with the shoulder
girdle as the arm rises; the controller's model (``CuffGeometry``: exit at ``a`` from the joint
centre, at ψ from the hanging humerus) assumes the exit keeps its place relative to the glenohumeral
centre, and the simulated plant moves the arm with that model's torque r(θ)·T. So here the exit
rides with the glenohumeral centre (its reaction acts there, on the scapula, which carries the
glenoid) and keeps its direction in the trunk: the cable's torque about the elevation is then the
controller's r(θ)·T within 4 % at 20–130°, and the muscles balance the cable that moved the arm. The
alternatives differ by far more and no measurement of the paper's cuff says which holds: an exit
fixed to the trunk gives +3 to +35 % (the centre rises with the rhythm), one fixed to the clavicle
−9 to −21 %, one fixed to the scapula −42 to −54 % (docs/simulation.md).

Requires the ``msk`` extra (``pip install 'bowden[msk]'``).
"""

from __future__ import annotations

import functools
import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bowden.errors import ParameterError
from bowden.model import CuffGeometry

PLANE = "elv_angle_r"
ELEVATION = "shoulder_elv_r"
ROTATION = "shoulder_rot_r"
ELBOW = "elbow_flexion_r"
COORDINATES = (PLANE, ELEVATION, ROTATION, ELBOW)  # the coordinates the muscles must balance
FORWARD_FLEXION_PLANE_RAD = math.pi / 2  # MoBL's plane of elevation: 0 abduction, 90° forward flexion
HAND_BODY = "thirdmc_r"  # the load is held in the hand; applied at the third metacarpal's origin
# Muscles that cross the shoulder or the elbow (MoBL's names); the wrist and hand muscles stay at rest.
ARM_MUSCLES = (
    "DELT1", "DELT2", "DELT3", "SUPSP", "INFSP", "SUBSC", "TMIN", "TMAJ", "PECM1", "PECM2", "PECM3",
    "LAT1", "LAT2", "LAT3", "CORB", "TRIlong", "TRIlat", "TRImed", "ANC", "SUP", "BIClong",
    "BICshort", "BRA", "BRD", "PT",
)
# Muscles the static optimisation does not recruit: the long head of the biceps shows no EMG
# activity in shoulder flexion, extension or rotation (slow and fast, with and without a 2.3 kg load)
# when the elbow is held extended and the forearm neutral (Levy et al. 2001, J Shoulder Elbow Surg
# 10:250, fine-wire EMG), as the paper's participants held theirs ("keep the elbow fully extended, but
# relaxed"); MoBL nevertheless gives it a flexion moment arm of 6-8 mm at 20-100°, which least
# Σ a² would use. Its elevation moment measured by stimulation is near zero from 60° up (Landin,
# Myers, Thompson, Castle & Porter 2008, J Electromyogr Kinesiol 18:270).
NOT_RECRUITED = ("BIClong",)


def recruitable(capacity_nm: NDArray[np.float64]) -> NDArray[np.float64]:
    """The capacity (..., muscles of :data:`ARM_MUSCLES`) with the :data:`NOT_RECRUITED` muscles'
    columns zero: least Σ a² then leaves them at rest (their passive forces still act)."""
    out = np.array(capacity_nm, dtype=np.float64, copy=True)
    for name in NOT_RECRUITED:
        out[..., ARM_MUSCLES.index(name)] = 0.0
    return out


def _mujoco() -> Any:
    try:
        import mujoco  # type: ignore[import-untyped]
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ParameterError(
            "the musculoskeletal participants need MuJoCo and MyoArm: pip install 'bowden[msk]'"
        ) from exc
    return mujoco


@functools.lru_cache(maxsize=1)
def _load() -> tuple[Any, Any]:
    try:
        import myo_sim  # type: ignore[import-untyped]
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ParameterError(
            "the musculoskeletal participants need myo-sim: pip install 'bowden[msk]'"
        ) from exc
    mujoco = _mujoco()
    # myo_sim attaches its arm with an empty prefix, which MuJoCo warns about (harmless here) by
    # appending to MUJOCO_LOG.TXT in the working directory: route its warnings to Python's instead.
    mujoco.set_mju_user_warning(lambda message: warnings.warn(f"MuJoCo: {message}", stacklevel=2))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model, data = myo_sim.load("myoarm")
    return model, data


@dataclass(frozen=True)
class MuscleState:
    """Muscle geometry and force at one posture and velocity.

    ``moment_arm_m[k, i]``: moment arm of muscle i about coordinate k (> 0: its pull moves the
    coordinate positively); ``active_force_n``: force at full activation minus the passive force;
    ``passive_force_n``: the force at zero activation (both ≥ 0, tension).
    """

    moment_arm_m: NDArray[np.float64]
    active_force_n: NDArray[np.float64]
    passive_force_n: NDArray[np.float64]


class MyoArm:
    """MyoArm in the study's posture: forward flexion, elbow extended, no humeral rotation.

    Parameters
    ----------
    plane_rad
        Plane of elevation (MoBL ``elv_angle_r``), rad.
    """

    def __init__(self, plane_rad: float = FORWARD_FLEXION_PLANE_RAD) -> None:
        self._mj = _mujoco()
        model, _ = _load()
        self.model = model
        self.data = self._mj.MjData(model)
        self.plane_rad = float(plane_rad)
        self.muscle_ids = np.array([model.actuator(name).id for name in ARM_MUSCLES])
        self._dof = {name: int(model.joint(name).dofadr[0]) for name in COORDINATES}
        self._couplings = {name: self._coupling_vector(name) for name in COORDINATES}

    def _coupling_vector(self, coordinate: str) -> NDArray[np.float64]:
        """dq/dx for coordinate x: 1 at its own dof, the constraint's slope at the joints it drives."""
        m = self.model
        vector = np.zeros(m.nv)
        joint = m.joint(coordinate).id
        vector[m.jnt_dofadr[joint]] = 1.0
        for i in range(m.neq):
            if m.eq_type[i] == self._mj.mjtEq.mjEQ_JOINT and m.eq_obj2id[i] == joint:
                polynomial = m.eq_data[i][:5]
                if np.any(polynomial[2:] != 0.0):
                    raise ParameterError(f"MyoArm's constraint {m.eq(i).name} is not linear")
                vector[m.jnt_dofadr[m.eq_obj1id[i]]] = polynomial[1]
        return vector

    @property
    def max_force_n(self) -> NDArray[np.float64]:
        """Maximal isometric forces of :data:`ARM_MUSCLES` (MuJoCo's muscle gain parameter 2), N."""
        return np.array([self.model.actuator_gainprm[i][2] for i in self.muscle_ids])

    def coupling(self, coordinate: str) -> NDArray[np.float64]:
        """The joint-space direction of ``coordinate`` (coupled joints included)."""
        return self._couplings[coordinate].copy()

    def set_state(self, elevation_rad: float, velocity_rad_s: float = 0.0) -> None:
        """Pose the arm at this humeral elevation (MoBL ``shoulder_elv_r``) and velocity."""
        m, d = self.model, self.data
        d.qpos[:] = m.qpos0
        d.qvel[:] = 0.0
        d.qpos[:] += self._couplings[PLANE] * self.plane_rad + self._couplings[ELEVATION] * elevation_rad
        d.qvel[:] = self._couplings[ELEVATION] * velocity_rad_s
        self._mj.mj_forward(m, d)

    def muscle_state(self, elevation_rad: float, velocity_rad_s: float = 0.0) -> MuscleState:
        """Moment arms (coordinates × :data:`ARM_MUSCLES`) and forces at this state."""
        self.set_state(elevation_rad, velocity_rad_s)
        m, d = self.model, self.data
        moment = np.zeros((m.nu, m.nv))
        self._mj.mju_sparse2dense(moment, d.actuator_moment, d.moment_rownnz, d.moment_rowadr,
                                  d.moment_colind)
        moment = moment[self.muscle_ids]
        # MuJoCo's actuator moment is the length gradient: a muscle shortening along x pulls x positively.
        arms = -np.stack([moment @ self._couplings[c] for c in COORDINATES])
        active, passive = [], []
        for i in self.muscle_ids:
            length, velocity = d.actuator_length[i], d.actuator_velocity[i]
            lengthrange, acc0 = m.actuator_lengthrange[i], m.actuator_acc0[i]
            gain = self._mj.mju_muscleGain(length, velocity, lengthrange, acc0, m.actuator_gainprm[i][:9])
            bias = self._mj.mju_muscleBias(length, lengthrange, acc0, m.actuator_biasprm[i][:9])
            active.append(-gain)  # MuJoCo's muscle forces are negative (pulling)
            passive.append(-bias)
        return MuscleState(arms, np.array(active), np.array(passive))

    def tendon_length_m(self, elevation_rad: float) -> NDArray[np.float64]:
        """Musculotendon lengths of :data:`ARM_MUSCLES` at this elevation, m."""
        self.set_state(elevation_rad)
        return np.array(self.data.actuator_length[self.muscle_ids])

    def cuff_points(self, geometry: CuffGeometry) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The cable's anchor on the upper-arm cuff and its exit on the shoulder cuff (world, m).

        The anchor lies on the humerus' long axis (glenohumeral centre to elbow) at ``b``; the exit at
        ``a`` from the glenohumeral centre, at ψ from the hanging humerus in the plane of elevation,
        riding with the glenohumeral centre in a direction fixed to the trunk.
        """
        m, d = self.model, self.data
        centre = d.xpos[m.body("humerus_r").id].copy()
        axis = d.xpos[m.body("ulna_r").id] - centre
        axis /= np.linalg.norm(axis)
        anchor = centre + geometry.anchor_distance_m * axis
        down = np.array([0.0, 0.0, -1.0])
        forward = np.array([math.sin(self.plane_rad - math.pi / 2) * -1.0, -math.sin(self.plane_rad), 0.0])
        forward /= np.linalg.norm(forward)
        psi = geometry.rest_angle_rad
        exit_point = centre + geometry.exit_distance_m * (math.cos(psi) * down + math.sin(psi) * forward)
        return anchor, exit_point

    def required_torques_nm(
        self,
        elevation_rad: float,
        velocity_rad_s: float,
        acceleration_rad_s2: float,
        *,
        hand_load_kg: float,
        cable_tension_n: float = 0.0,
        geometry: CuffGeometry | None = None,
    ) -> NDArray[np.float64]:
        """Torque the muscles must make about each of :data:`COORDINATES` (inverse dynamics), Nm.

        The arm's own dynamics (MuJoCo's recursive Newton-Euler with gravity), minus the hand load's
        and the cable's generalised forces, projected on each coordinate's direction.
        """
        m, d = self.model, self.data
        self.set_state(elevation_rad, velocity_rad_s)
        d.qacc[:] = self._couplings[ELEVATION] * acceleration_rad_s2
        dynamics = np.zeros(m.nv)
        self._mj.mj_rne(m, d, 1, dynamics)
        external = self._point_force(HAND_BODY, d.xpos[m.body(HAND_BODY).id],
                                     hand_load_kg * np.asarray(m.opt.gravity))  # the model's g, 9.81
        if cable_tension_n != 0.0:
            external += self._cable_force(geometry or CuffGeometry(), cable_tension_n)
        net = dynamics - external
        return np.array([self._couplings[c] @ net for c in COORDINATES])

    def _cable_force(self, geometry: CuffGeometry, tension_n: float) -> NDArray[np.float64]:
        """The cable's generalised force at the current state (the module's docstring: where it rides).

        The tension pulls the anchor on the humerus toward the exit, and the exit back toward the
        anchor; the exit rides with the glenohumeral centre, so its reaction acts there, on the scapula.
        """
        anchor, exit_point = self.cuff_points(geometry)
        pull = tension_n * (exit_point - anchor) / np.linalg.norm(exit_point - anchor)
        centre = self.data.xpos[self.model.body("humerus_r").id].copy()
        return self._point_force("humerus_r", anchor, pull) - self._point_force("scapula_r", centre, pull)

    def cable_torque_nm(self, elevation_rad: float, tension_n: float, geometry: CuffGeometry) -> float:
        """The cable's torque about the humeral elevation (generalised force along its direction), Nm."""
        self.set_state(elevation_rad)
        return float(self._couplings[ELEVATION] @ self._cable_force(geometry, tension_n))

    def _point_force(
        self, body: str, point: NDArray[np.float64], force: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        m, d = self.model, self.data
        jacobian = np.zeros((3, m.nv))
        self._mj.mj_jac(m, d, jacobian, None, point, m.body(body).id)
        return np.asarray(jacobian.T @ force)
