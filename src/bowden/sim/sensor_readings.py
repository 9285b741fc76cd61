"""Readings of the simulated suit's sensors at their real resolution, as their drivers decode them.

The real suit's signals arrive as integer codes or float32, and so do the batch simulation's:

* the AK60-6 replies with a 12-bit velocity and a 12-bit torque code (:mod:`bowden.hardware.ak60_codec`):
  a value is encoded as the motor does (:func:`~bowden.hardware.ak60_codec.float_to_uint`, clamped
  to the field's range, half-up rounding) and decoded with the driver's
  :func:`~bowden.hardware.ak60_codec.uint_to_float` and direction;
* the ADS1115 converts the amplifier's voltage to a 16-bit code (as the simulated peer does,
  :class:`bowden.sim.peers.ADS1115Peer`), read back with the driver's
  :func:`~bowden.hardware.ads1115.code_to_volts` and calibration;
* the NGIMU sends float32 over OSC: its elevation and velocity are rounded to float32 inside the
  compiled trial (:func:`bowden.sim._batch_kernel.run_trial`), where the controller reads them.

So a simulated trial holds the values the wire path (``bowden run --backend sim``) and a real
recording can hold, and the store keeps them as codes (:mod:`bowden.store.sensor_grids`).
Arrays in, arrays out; NaN (no suit) stays NaN.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from bowden.hardware.ads1115 import LoadCellCalibration, code_to_volts
from bowden.hardware.ak60_codec import TORQUE_BITS, VELOCITY_BITS, AK60Limits, limits_for_motor, uint_to_float
from bowden.sim.parameters import LoadCellParameters

# The field ranges the AK60 driver is configured with by default (AK60Config), as on the wire path.
MOTOR_REPLY_LIMITS = limits_for_motor("AK60-6")


def ak60_reading(
    values: NDArray[np.float64], bound: float, bits: int, direction: int = 1
) -> NDArray[np.float64]:
    """What the driver reads for ``values`` sent in a ±``bound`` field of ``bits`` bits."""
    sent = direction * values  # the motor's own sense
    code = np.floor((np.clip(sent, -bound, bound) + bound) * ((1 << bits) - 1) / (2.0 * bound) + 0.5)
    finite = np.isfinite(code)
    out = np.full(values.shape, np.nan)
    out[finite] = direction * uint_to_float(code[finite].astype(np.int64), -bound, bound, bits)
    return out


def ak60_velocity(values: NDArray[np.float64], limits: AK60Limits) -> NDArray[np.float64]:
    """The reply's velocity field (rad/s) as read."""
    return ak60_reading(values, limits.velocity_rad_s, VELOCITY_BITS)


def ak60_torque(values: NDArray[np.float64], limits: AK60Limits) -> NDArray[np.float64]:
    """The reply's torque field (Nm) as read."""
    return ak60_reading(values, limits.torque_nm, TORQUE_BITS)


def load_cell_reading(tension_n: NDArray[np.float64], cell: LoadCellParameters) -> NDArray[np.float64]:
    """What the ADS1115 driver reads for the amplifier's output at ``tension_n`` (N)."""
    volts = cell.adc_offset_v + (1.0 / cell.gain_n_per_v) * tension_n  # the peer's volts per newton
    code = np.clip(np.floor(volts / cell.adc_full_scale_v * 32768.0 + 0.5), -32768, 32767)
    finite = np.isfinite(code)
    calibration = LoadCellCalibration(offset_v=cell.adc_offset_v, gain_n_per_v=cell.gain_n_per_v)
    out = np.full(tension_n.shape, np.nan)
    out[finite] = calibration.tension_n(code_to_volts(code[finite].astype(np.int64), cell.adc_full_scale_v))
    return out
