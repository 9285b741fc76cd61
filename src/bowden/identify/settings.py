"""The identification's light names: directions, the preprocessing settings, the default IMU latency.

The command line reads these while it builds its parser (defaults and help texts), so this module
imports neither NumPy nor the fitting libraries: ``bowden --help`` must not pay for statsmodels,
SciPy's statistics or matplotlib. :mod:`bowden.identify.preprocess` and :mod:`bowden.identify.dynamic`
re-export them where they were defined before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bowden.errors import ParameterError

RAISING = "raising"
LOWERING = "lowering"
DIRECTIONS = (RAISING, LOWERING)

# NGIMU orientation over OSC/UDP on WiFi arrives some tens of ms old. Assuming too much latency costs
# little and too little costs much (docs/control.md), so the default sits at the top of the 10–50 ms
# the simulated family spans.
DEFAULT_IMU_LATENCY_S = 0.05


@dataclass(frozen=True, kw_only=True)
class PreprocessSettings:
    """Filter and steady-state selection settings (defaults: the paper's).

    Parameters
    ----------
    cutoff_hz
        Low-pass cutoff of the zero-phase Butterworth filter, Hz (paper: 5).
    filter_order
        Butterworth order (paper: 3).
    min_speed_rad_s
        Keep samples with |spool velocity| above this, rad/s (paper: 15 °/s).
    max_abs_acceleration_rad_s2
        Keep samples with |spool acceleration| below this, rad/s² (paper: 15 °/s²).
    min_elevation_rad, max_elevation_rad
        Keep samples with elevation strictly between these, rad (paper: 20° and 90°).
    min_torque_nm
        Keep samples with filtered motor torque above this, Nm (paper: 0).
    gap_factor
        A time step longer than this multiple of the segment's median step starts a new segment.
    """

    cutoff_hz: float = 5.0
    filter_order: int = 3
    min_speed_rad_s: float = math.radians(15.0)
    max_abs_acceleration_rad_s2: float = math.radians(15.0)
    min_elevation_rad: float = math.radians(20.0)
    max_elevation_rad: float = math.radians(90.0)
    min_torque_nm: float = 0.0
    gap_factor: float = 3.0

    def __post_init__(self) -> None:
        def finite(name: str) -> float:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise ParameterError(f"{name} must be a finite number, got {value!r}")
            return float(value)

        for name in ("cutoff_hz", "max_abs_acceleration_rad_s2"):
            if finite(name) <= 0.0:
                raise ParameterError(f"{name} must be positive, got {getattr(self, name)!r}")
        if finite("min_speed_rad_s") < 0.0:
            raise ParameterError(f"min_speed_rad_s must be >= 0, got {self.min_speed_rad_s!r}")
        finite("min_torque_nm")
        if not finite("min_elevation_rad") < finite("max_elevation_rad"):
            raise ParameterError(
                f"min_elevation_rad ({self.min_elevation_rad!r}) must be below "
                f"max_elevation_rad ({self.max_elevation_rad!r})"
            )
        if finite("gap_factor") <= 1.0:
            raise ParameterError(f"gap_factor must exceed 1, got {self.gap_factor!r}")
        if isinstance(self.filter_order, bool) or not isinstance(self.filter_order, int):
            raise ParameterError(f"filter_order must be an integer, got {self.filter_order!r}")
        if not 1 <= self.filter_order <= 8:
            raise ParameterError(f"filter_order must be between 1 and 8, got {self.filter_order!r}")

    def criterion_labels(self) -> dict[str, str]:
        """Human-readable label of each selection criterion, in degrees as the paper states them."""
        return {
            "speed": f"|spool speed| > {math.degrees(self.min_speed_rad_s):g} °/s",
            "acceleration": f"|spool acceleration| < {math.degrees(self.max_abs_acceleration_rad_s2):g} °/s²",
            "elevation": (
                f"{math.degrees(self.min_elevation_rad):g}° < elevation < "
                f"{math.degrees(self.max_elevation_rad):g}°"
            ),
            "torque": f"motor torque > {self.min_torque_nm:g} Nm",
        }
