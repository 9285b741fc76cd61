"""What moves the arm of a simulated suit: prescribed kinematics, a mannequin, or a virtual participant.

An arm driver tells the plant how the arm is driven (a mode of :mod:`bowden.sim._kernels`), which arm
the cable pulls on, and the per-step inputs for a stretch of simulated time.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from bowden.errors import ParameterError
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.sim import _kernels as k
from bowden.sim.parameters import ArmParameters
from bowden.sim.participants import ExpectedAssistance, VirtualParticipant, human_vector

ArrayFunction = Callable[[NDArray[np.float64]], NDArray[np.float64]]


class ArmDriver(Protocol):
    """How the arm of a simulated suit moves."""

    @property
    def mode(self) -> int:
        """``ARM_PRESCRIBED``, ``ARM_TORQUE``, ``ARM_HUMAN`` or ``ARM_IMPEDANCE`` (sim._kernels)."""
        ...

    @property
    def arm_parameters(self) -> ArmParameters:
        """The arm the cable pulls on."""
        ...

    def initial_elevation_rad(self) -> float:
        """Where the arm is at time 0."""
        ...

    def inputs(
        self, times_s: NDArray[np.float64], rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Per-step inputs (``arm_a``, ``arm_b``) at the end times of the coming steps."""
        ...

    def human(self) -> NDArray[np.float64] | None:
        """The participant vector for ``ARM_HUMAN``, the motor's command for ``ARM_IMPEDANCE``, else None."""
        ...


@dataclass(frozen=True, kw_only=True)
class PrescribedArm:
    """An arm that moves as told whatever the cable does: enough for tension-tracking studies.

    Parameters
    ----------
    elevation_rad, elevation_velocity_rad_s
        Vectorised functions of time (s) → elevation (rad) and its velocity (rad/s).
    """

    elevation_rad: ArrayFunction
    elevation_velocity_rad_s: ArrayFunction
    arm_parameters: ArmParameters = field(default_factory=ArmParameters)

    @property
    def mode(self) -> int:
        return k.ARM_PRESCRIBED

    @classmethod
    def hold(cls, elevation_rad: float) -> PrescribedArm:
        """An arm held still at ``elevation_rad``."""
        return cls(
            elevation_rad=lambda t: np.full_like(t, elevation_rad),
            elevation_velocity_rad_s=np.zeros_like,
        )

    @classmethod
    def following(cls, cycle: MinimumJerkCycle, *, start_s: float = 0.0) -> PrescribedArm:
        """An arm that follows ``cycle`` exactly from ``start_s`` on (resting at its low point before)."""

        def elevation(t: NDArray[np.float64]) -> NDArray[np.float64]:
            return cycle.elevation_rad(np.maximum(t - start_s, 0.0))

        def velocity(t: NDArray[np.float64]) -> NDArray[np.float64]:
            moving = t > start_s
            return np.where(moving, cycle.elevation_velocity_rad_s(np.maximum(t - start_s, 0.0)), 0.0)

        return cls(elevation_rad=elevation, elevation_velocity_rad_s=velocity)

    def initial_elevation_rad(self) -> float:
        return float(self.elevation_rad(np.zeros(1))[0])

    def inputs(
        self, times_s: NDArray[np.float64], rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return self.elevation_rad(times_s), self.elevation_velocity_rad_s(times_s)

    def human(self) -> NDArray[np.float64] | None:
        return None


class MannequinArm:
    """The bench's motorised mannequin arm, its joint motor loading the cable.

    ``load_torque_nm`` (> 0 pulls the arm down, against the cable) is the mannequin motor's torque
    command and may be changed between calls, as the bench does; :meth:`hold_impedance` puts the motor
    in MIT mode instead (the bench's latency and study-like segments), evaluated at every plant step.
    """

    def __init__(
        self,
        parameters: ArmParameters | None = None,
        *,
        load_torque_nm: float = 0.0,
        initial_elevation_rad: float = math.radians(20.0),
    ) -> None:
        self._parameters = parameters if parameters is not None else ArmParameters()
        self._load_torque_nm = load_torque_nm
        self._impedance: NDArray[np.float64] | None = None
        self._initial = initial_elevation_rad

    @property
    def load_torque_nm(self) -> float:
        """The torque command (> 0 lowers the arm); in MIT mode, its feedforward torque."""
        return self._load_torque_nm

    @load_torque_nm.setter
    def load_torque_nm(self, torque_nm: float) -> None:
        self._load_torque_nm = torque_nm
        self._impedance = None  # a torque command ends MIT mode

    def hold_impedance(self, elevation_rad: float, elevation_velocity_rad_s: float, kp_nm_rad: float,
                       kd_nms_rad: float, load_torque_nm: float, torque_limit_nm: float) -> None:
        """MIT mode about ``elevation_rad`` (the arm's sense), with ``load_torque_nm`` (> 0 lowers the
        arm) as its feedforward and the motor's peak torque as the limit, from now on."""
        values = (elevation_rad, elevation_velocity_rad_s, kp_nm_rad, kd_nms_rad, load_torque_nm,
                  torque_limit_nm)
        if not all(math.isfinite(v) for v in values) or kp_nm_rad < 0.0 or kd_nms_rad < 0.0:
            raise ParameterError(f"MannequinArm.hold_impedance needs finite values and kp, kd >= 0, "
                                 f"got {values!r}")
        self._load_torque_nm = load_torque_nm
        self._impedance = np.array([elevation_rad, elevation_velocity_rad_s, kp_nm_rad, kd_nms_rad,
                                    -load_torque_nm, torque_limit_nm])

    @property
    def mode(self) -> int:
        return k.ARM_TORQUE if self._impedance is None else k.ARM_IMPEDANCE

    @property
    def arm_parameters(self) -> ArmParameters:
        return self._parameters

    def initial_elevation_rad(self) -> float:
        return self._initial

    def inputs(
        self, times_s: NDArray[np.float64], rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        if not math.isfinite(self._load_torque_nm):
            raise ParameterError(f"MannequinArm.load_torque_nm must be finite, got {self._load_torque_nm!r}")
        return np.full_like(times_s, -self._load_torque_nm), np.zeros_like(times_s)

    def human(self) -> NDArray[np.float64] | None:
        return self._impedance


class ParticipantArm:
    """A virtual participant's arm tracking a minimum-jerk reference shown on a screen.

    Parameters
    ----------
    participant
        Who moves (arm inertia and gravity, visuomotor lag, impedance, motor noise).
    cycle
        The reference shown (paper: 20° → 100° → 20° at 60, 120 or 180 °/s peak).
    cycles
        Number of raise-and-lower repetitions (paper: 10).
    start_s
        When the reference starts moving; before and after it rests at its low point.
    expected
        The assistance the participant expects (the controller's nominal law), or None without a suit.
    """

    def __init__(
        self,
        participant: VirtualParticipant,
        cycle: MinimumJerkCycle,
        *,
        cycles: int = 10,
        start_s: float = 1.0,
        expected: ExpectedAssistance | None = None,
    ) -> None:
        self.participant = participant
        self.cycle = cycle
        self._h = human_vector(participant, cycle, cycles=cycles, start_s=start_s, expected=expected)
        self._arm = participant.arm_parameters()

    @property
    def mode(self) -> int:
        return k.ARM_HUMAN

    @property
    def arm_parameters(self) -> ArmParameters:
        return self._arm

    def initial_elevation_rad(self) -> float:
        return float(self._h[k.H_REF_LOW] + self._h[k.H_OFFSET])

    def inputs(
        self, times_s: NDArray[np.float64], rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        draws = np.asarray(rng.standard_normal((2, times_s.shape[0])), dtype=np.float64)
        return np.ascontiguousarray(draws[0]), np.ascontiguousarray(draws[1])

    def human(self) -> NDArray[np.float64] | None:
        return self._h
