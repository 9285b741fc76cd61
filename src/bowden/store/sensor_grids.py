"""Sensor grids: the values a sensor that reports integer codes can take, decoded as its driver does.

The AK60-6 replies with 12-bit velocity and torque codes and the ADS1115 load cell converts to
16-bit codes; their drivers turn a code into SI units with one formula each
(:func:`bowden.hardware.ak60_codec.uint_to_float`, :func:`bowden.hardware.ads1115.code_to_volts` and
:meth:`bowden.hardware.ads1115.LoadCellCalibration.tension_n`). A column of such readings lies exactly
on a grid — every value is ``decode(code)`` for an integer code, bit for bit — and the store keeps the
codes instead of the float64 values (:mod:`bowden.store.column_codec`, filter ``grid``): a grid is
named in a chunk's header by its formula and parameters, and decoding calls the same functions.

:data:`KNOWN_GRIDS` lists, per recorded column, the grids of the devices this toolkit configures; the
codec tries them in order and keeps a grid only where it reproduces every value exactly.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from bowden.contracts import TRIAL_MOTOR_TORQUE, TRIAL_MOTOR_VELOCITY, TRIAL_TENSION
from bowden.errors import ParameterError, StoreError
from bowden.hardware.ads1115 import FULL_SCALE_V, LoadCellCalibration, code_to_volts
from bowden.hardware.ak60_codec import (
    FIRMWARE_LIMITS,
    MOTOR_LIMITS,
    TORQUE_BITS,
    VELOCITY_BITS,
    uint_to_float,
)

AK60: Final = "ak60"  # sign · uint_to_float(code, low, high, bits); params (low, high, bits, sign)
ADS1115: Final = "ads1115"  # LoadCellCalibration(offset, gain).tension_n(code_to_volts(code, fs))
_PARAMS: Final = {AK60: 4, ADS1115: 3}


@dataclass(frozen=True)
class Grid:
    """One sensor's grid: a formula id and its parameters (see the module's formulas).

    Raises
    ------
    StoreError
        An unknown formula, the wrong number of parameters or parameters the formula rejects.
    """

    formula: str
    params: tuple[float, ...]

    def __post_init__(self) -> None:
        if self.formula not in _PARAMS:
            raise StoreError(f"unknown sensor grid formula {self.formula!r} (known: {', '.join(_PARAMS)})")
        if len(self.params) != _PARAMS[self.formula] or not all(np.isfinite(self.params)):
            raise StoreError(f"sensor grid {self.formula!r} needs {_PARAMS[self.formula]} finite parameters, "
                             f"got {list(self.params)!r}")
        if self.formula == AK60:
            low, high, bits, sign = self.params
            if not (high > low and bits in (8, 12, 16) and sign in (1.0, -1.0)):
                raise StoreError(f"sensor grid ak60: bad parameters {list(self.params)!r}")
        else:
            try:
                self._calibration()
            except ParameterError as error:
                raise StoreError(f"sensor grid ads1115: {error}") from None

    def _calibration(self) -> LoadCellCalibration:
        return LoadCellCalibration(offset_v=self.params[1], gain_n_per_v=self.params[2])

    def decode(self, codes: NDArray[np.integer[Any]]) -> NDArray[np.float64]:
        """The values of ``codes``, as the driver computes them (float64)."""
        wide = codes.astype(np.int64)
        if self.formula == AK60:
            low, high, bits, sign = self.params
            return sign * uint_to_float(wide, low, high, int(bits))  # the driver: direction · value
        values: NDArray[np.float64] = self._calibration().tension_n(code_to_volts(wide, self.params[0]))
        return values

    def nearest_codes(self, values: NDArray[np.float64]) -> NDArray[np.float64]:
        """The code nearest to each value (as a float; NaN stays NaN): a candidate, checked by decoding."""
        with np.errstate(over="ignore", invalid="ignore"):  # huge values: out of range, rejected later
            if self.formula == AK60:
                low, high, bits, sign = self.params
                return np.rint((sign * values - low) * ((1 << int(bits)) - 1) / (high - low))
            full_scale, offset, gain = self.params
            return np.rint((values / gain + offset) * 32768.0 / full_scale)

    def header(self) -> dict[str, Any]:
        return {"formula": self.formula, "params": list(self.params)}

    @classmethod
    def from_header(cls, header: Mapping[str, Any]) -> Grid:
        try:
            return cls(str(header["formula"]), tuple(float(value) for value in header["params"]))
        except (KeyError, TypeError, ValueError) as error:
            raise StoreError(f"a stored sensor grid is malformed ({error})") from None


def ak60_grids(bits: int, attribute: str) -> tuple[Grid, ...]:
    """The grids of one AK-series reply field over every preset range, both directions."""
    presets = (*MOTOR_LIMITS.values(), *FIRMWARE_LIMITS.values())
    ranges = sorted({getattr(limits, attribute) for limits in presets})
    return tuple(Grid(AK60, (-r, r, float(bits), s)) for r in ranges for s in (1.0, -1.0))


# The load-cell calibrations this toolkit configures: the driver's default and the simulated suit's
# (0.05 V at no load, 100 N/V: bowden run --backend sim and the batch simulation,
# bowden.sim.parameters.LoadCellParameters). A lab's own calibration falls back to the xor filter.
LOAD_CELL_CALIBRATIONS: Final = ((0.0, 100.0), (0.05, 100.0))

KNOWN_GRIDS: Final[Mapping[str, tuple[Grid, ...]]] = {
    TRIAL_MOTOR_TORQUE: ak60_grids(TORQUE_BITS, "torque_nm"),
    TRIAL_MOTOR_VELOCITY: ak60_grids(VELOCITY_BITS, "velocity_rad_s"),
    TRIAL_TENSION: tuple(
        Grid(ADS1115, (fs, offset, gain))
        for offset, gain in LOAD_CELL_CALIBRATIONS[::-1]
        for fs in sorted(set(FULL_SCALE_V))
    ),
}
