"""The controller's output and the safe command shared by its compensation laws (off the hot path)."""

from __future__ import annotations

import math
from operator import itemgetter
from typing import Protocol

from bowden.control.faults import Fault

_NAN = math.nan


class Command(tuple[float, float, float, int, int]):
    """One cycle's output, a 5-tuple with named fields.

    torque_nm
        Motor torque to command, Nm (spool side, ≥ 0; 0 on a fault).
    tension_n
        Desired cable tension at the arm anchor, N (NaN on a fault).
    moment_arm_m
        Cable moment arm r(θ) of this cycle, m (NaN on a fault).
    faults
        :class:`Fault` bits (0: none).
    limits
        :class:`Limit` bits: which limits shaped the command.

    Built on the hot path as ``Command((torque, tension, arm, faults, limits))``: tuple's own C
    constructor, about 40 % cheaper than a NamedTuple's Python ``__new__``. :meth:`of` takes keywords.
    """

    __slots__ = ()
    _fields = ("torque_nm", "tension_n", "moment_arm_m", "faults", "limits")

    torque_nm = property(itemgetter(0), doc="Motor torque to command, Nm.")
    tension_n = property(itemgetter(1), doc="Desired cable tension at the arm, N.")
    moment_arm_m = property(itemgetter(2), doc="Cable moment arm of this cycle, m.")
    faults = property(itemgetter(3), doc="Fault bits (0: none).")
    limits = property(itemgetter(4), doc="Limit bits.")

    @classmethod
    def of(
        cls, *, torque_nm: float, tension_n: float, moment_arm_m: float, faults: int = 0, limits: int = 0
    ) -> Command:
        """A command from keywords."""
        return cls((torque_nm, tension_n, moment_arm_m, faults, limits))

    def _asdict(self) -> dict[str, float | int]:
        return dict(zip(self._fields, self, strict=True))

    def __repr__(self) -> str:
        fields = ", ".join(f"{name}={value!r}" for name, value in zip(self._fields, self, strict=True))
        return f"Command({fields})"


class StepFunction(Protocol):
    """Signature of :attr:`Controller.step`."""

    def __call__(
        self,
        time_s: float,
        elevation_rad: float,
        elevation_velocity_rad_s: float,
        motor_velocity_rad_s: float = _NAN,
        motor_torque_nm: float = _NAN,
    ) -> Command: ...


_NONFINITE = int(Fault.NONFINITE_INPUT)
_ELEVATION = int(Fault.ELEVATION_OUT_OF_RANGE)
_VELOCITY = int(Fault.ELEVATION_VELOCITY_OUT_OF_RANGE)
_OVERSPEED = int(Fault.MOTOR_OVERSPEED)


def fault_bits(
    time_s: float,
    elevation_rad: float,
    elevation_velocity_rad_s: float,
    motor_velocity_rad_s: float,
    motor_torque_nm: float,
    elev_min: float,
    elev_max: float,
    max_vel: float,
    max_motor_vel: float,
) -> int:
    """The :class:`Fault` bits of inputs the step refused (plain arithmetic: the batch kernel compiles it)."""
    faults = 0
    finite = (math.isfinite(time_s) and math.isfinite(elevation_rad)
              and math.isfinite(elevation_velocity_rad_s))
    if not finite or math.isinf(motor_velocity_rad_s) or math.isinf(motor_torque_nm):
        faults |= _NONFINITE
    if math.isfinite(elevation_rad) and not elev_min <= elevation_rad <= elev_max:
        faults |= _ELEVATION
    if math.isfinite(elevation_velocity_rad_s) and abs(elevation_velocity_rad_s) > max_vel:
        faults |= _VELOCITY
    if math.isfinite(motor_velocity_rad_s) and abs(motor_velocity_rad_s) > max_motor_vel:
        faults |= _OVERSPEED
    return faults


def fault_command(
    time_s: float,
    elevation_rad: float,
    elevation_velocity_rad_s: float,
    motor_velocity_rad_s: float,
    motor_torque_nm: float,
    elev_min: float,
    elev_max: float,
    max_vel: float,
    max_motor_vel: float,
) -> Command:
    """The safe command (zero torque), with flags saying which input was wrong (off the hot path)."""
    faults = fault_bits(time_s, elevation_rad, elevation_velocity_rad_s, motor_velocity_rad_s,
                        motor_torque_nm, elev_min, elev_max, max_vel, max_motor_vel)
    return Command((0.0, _NAN, _NAN, faults, 0))
