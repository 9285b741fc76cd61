"""Safety limits of the controller, with the AK60-6 suit of the paper as defaults."""

from __future__ import annotations

import math
from dataclasses import dataclass

from bowden.errors import ParameterError


@dataclass(frozen=True, kw_only=True)
class ControllerLimits:
    """Limits applied by :meth:`bowden.control.Controller.step`.

    Parameters
    ----------
    min_torque_nm, max_torque_nm
        Commanded motor torque range, Nm. The minimum is ≥ 0 because a cable cannot push; the maximum
        should stay within the motor's configured torque limit (AK60-6: rated 3 Nm, peak 9 Nm).
    max_tension_n
        Highest desired cable tension, N.
    max_torque_rate_nm_s
        Largest change of commanded torque per second, Nm/s (steps are ramped).
    nominal_period_s
        Control period assumed when the time step is unknown (first cycle, repeated or late time).
    elevation_min_rad, elevation_max_rad
        Plausible humeral elevation; outside it the sensor is wrong or the arm is where the suit
        cannot help: the command is the safe one.
    max_elevation_velocity_rad_s, max_motor_velocity_rad_s
        Plausible elevation velocity and spool velocity magnitudes (the latter only checked when given).
    """

    min_torque_nm: float = 0.0
    max_torque_nm: float = 6.0
    max_tension_n: float = 150.0
    max_torque_rate_nm_s: float = 200.0
    nominal_period_s: float = 0.002
    elevation_min_rad: float = math.radians(-30.0)
    elevation_max_rad: float = math.radians(150.0)
    max_elevation_velocity_rad_s: float = 20.0
    max_motor_velocity_rad_s: float = 45.0

    def __post_init__(self) -> None:
        for name in (
            "min_torque_nm",
            "max_torque_nm",
            "max_tension_n",
            "max_torque_rate_nm_s",
            "nominal_period_s",
            "elevation_min_rad",
            "elevation_max_rad",
            "max_elevation_velocity_rad_s",
            "max_motor_velocity_rad_s",
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise ParameterError(f"{name} must be a finite number, got {value!r}")
        if self.min_torque_nm < 0.0:
            raise ParameterError(
                f"min_torque_nm must be >= 0 (a cable cannot push), got {self.min_torque_nm!r}"
            )
        if not self.max_torque_nm > self.min_torque_nm:
            raise ParameterError(
                f"max_torque_nm ({self.max_torque_nm!r}) must exceed min_torque_nm ({self.min_torque_nm!r})"
            )
        for name in ("max_tension_n", "max_torque_rate_nm_s", "nominal_period_s",
                     "max_elevation_velocity_rad_s", "max_motor_velocity_rad_s"):
            if not getattr(self, name) > 0.0:
                raise ParameterError(f"{name} must be positive, got {getattr(self, name)!r}")
        if not self.elevation_max_rad > self.elevation_min_rad:
            raise ParameterError("elevation_max_rad must exceed elevation_min_rad")
