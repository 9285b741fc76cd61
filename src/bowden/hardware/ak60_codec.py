"""Bit-exact frames of the T-motor (CubeMars) AK60-6 V1.1 in MIT mode.

Source: CubeMars AK-series driver manual V1.0.8, §5.3 (MIT/"servo-less" mode). CAN 2.0, 1 Mbit/s,
standard 11-bit identifier = motor id.

Special frames (8 data bytes): ``FF FF FF FF FF FF FF FC`` enters motor mode, ``… FD`` exits it,
``… FE`` makes the current position zero (the motor is silent for ~0.5–1.5 s afterwards).

Command frame (8 bytes, big-endian bit fields)::

    p_des 16 | v_des 12 | Kp 12 | Kd 12 | t_ff 12
    b0 = p[15:8]   b1 = p[7:0]
    b2 = v[11:4]   b3 = v[3:0] << 4 | Kp[11:8]
    b4 = Kp[7:0]   b5 = Kd[11:4]
    b6 = Kd[3:0] << 4 | t[11:8]    (the manual's sample code gets this byte wrong; its table is right)
    b7 = t[7:0]

Reply frame (6 bytes on older firmware, 8 on newer)::

    b0 = motor id   b1 b2 = p 16   b3 = v[11:4]   b4 = v[3:0] << 4 | t[11:8]   b5 = t[7:0]
    b6 = temperature byte          b7 = error code   (8-byte replies only)

A float x maps to an n-bit field as round((clamp(x) − min)·(2ⁿ − 1)/(max − min)). The ranges are not
agreed between sources (velocity ±45 or ±50 rad/s, torque ±15 or ±9 Nm) and a wrong torque range
silently rescales every command, so they are configuration (:class:`AK60Limits`), never constants.
Zero is not on the grid of a symmetric field (2ⁿ − 1 steps): a zero torque goes out as +½ step
(3.7 mNm at ±15 Nm), so a motor is only truly limp after the exit-motor-mode frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum
from typing import Any, Final, overload

import numpy as np
from numpy.typing import NDArray

from bowden.errors import MalformedFrameError, ParameterError

MOTOR_MODE_PREFIX: Final = b"\xff" * 7
ENTER_MOTOR_MODE: Final = MOTOR_MODE_PREFIX + b"\xfc"
EXIT_MOTOR_MODE: Final = MOTOR_MODE_PREFIX + b"\xfd"
SET_ZERO: Final = MOTOR_MODE_PREFIX + b"\xfe"
SPECIAL_FRAMES: Final = (ENTER_MOTOR_MODE, EXIT_MOTOR_MODE, SET_ZERO)

POSITION_BITS: Final = 16
VELOCITY_BITS: Final = 12
GAIN_BITS: Final = 12
TORQUE_BITS: Final = 12
MAX_STANDARD_ID: Final = 0x7FF


class MotorErrorCode(IntEnum):
    """Error codes in byte 7 of an 8-byte reply (CubeMars manual V1.0.8 §5.3)."""

    NONE = 0
    OVER_TEMPERATURE = 1
    OVER_CURRENT = 2
    OVER_VOLTAGE = 3
    UNDER_VOLTAGE = 4
    ENCODER = 5
    PHASE_IMBALANCE = 6

    @classmethod
    def describe(cls, code: int) -> str:
        """Human-readable name of ``code``; unknown codes are named by number, never rejected."""
        try:
            return cls(code).name.lower().replace("_", " ")
        except ValueError:
            return f"unknown error code {code}"


@dataclass(frozen=True, kw_only=True)
class AK60Limits:
    """Field ranges of one firmware variant (symmetric ±, except the gains which start at 0).

    Parameters
    ----------
    position_rad
        Position range ±P (rad, output shaft). Manual: 12.5.
    velocity_rad_s
        Velocity range ±V (rad/s). Manual V1.0.8: 45; other public drivers: 50.
    torque_nm
        Torque range ±T (Nm, output shaft). Manual V1.0.8: 15; other public drivers: 9 (the peak torque).
    kp_max
        Upper end of the position gain field (Nm/rad). 500.
    kd_max
        Upper end of the damping gain field (Nm·s/rad). 5.
    temperature_offset_c, temperature_scale_c
        Temperature byte → °C as ``offset + scale·byte``. The scale on V1.1 is unverified
        (CubeMars driver manual V1.0.8); newer CubeMars documents give byte − 40.
    """

    position_rad: float = 12.5
    velocity_rad_s: float = 45.0
    torque_nm: float = 15.0
    kp_max: float = 500.0
    kd_max: float = 5.0
    temperature_offset_c: float = -40.0
    temperature_scale_c: float = 1.0

    def __post_init__(self) -> None:
        for name in ("position_rad", "velocity_rad_s", "torque_nm", "kp_max", "kd_max",
                     "temperature_scale_c"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ParameterError(f"AK60Limits.{name} must be positive and finite, got {value!r}")
        if not math.isfinite(self.temperature_offset_c):
            raise ParameterError(
                f"AK60Limits.temperature_offset_c must be finite, got {self.temperature_offset_c!r}"
            )


FIRMWARE_LIMITS: Final[dict[str, AK60Limits]] = {
    # CubeMars AK-series driver manual V1.0.8 §5.3.
    "manual-v1.0.8": AK60Limits(velocity_rad_s=45.0, torque_nm=15.0),
    # The ranges used by several public MIT-mode drivers for the AK60-6 (torque range = peak torque).
    "peak-9nm": AK60Limits(velocity_rad_s=50.0, torque_nm=9.0),
}
DEFAULT_FIRMWARE: Final = "manual-v1.0.8"

# Other AK-series motors speak the same MIT-mode frames with their own field ranges: the table of
# CubeMars "AK Series Actuator Driver Manual" V1.0.8 §5.3 (p. 50; position ±12.5 rad, Kp 0–500, Kd 0–5
# for every model). neurobionics/TMotorCANControl (mit_can.py MIT_Params, commit bb8d071) has the same
# ranges except the AK60-6's velocity (±50). The bench's mannequin motor is typically an AK80-9; IHMC's
# tMotorCore gives it ±41.87 rad/s, so check yours as docs/hardware.md §1 item 5 says. The motors'
# gear ratios and torque constants are in :mod:`bowden.hardware.motors`.
MOTOR_LIMITS: Final[dict[str, AK60Limits]] = {
    "AK10-9": AK60Limits(velocity_rad_s=50.0, torque_nm=65.0),
    "AK60-6": FIRMWARE_LIMITS[DEFAULT_FIRMWARE],
    "AK70-10": AK60Limits(velocity_rad_s=50.0, torque_nm=25.0),
    "AK80-6": AK60Limits(velocity_rad_s=76.0, torque_nm=12.0),
    "AK80-9": AK60Limits(velocity_rad_s=50.0, torque_nm=18.0),
    "AK80-64": AK60Limits(velocity_rad_s=8.0, torque_nm=144.0),
}


def limits_for_motor(name: str) -> AK60Limits:
    """The field ranges of the AK-series motor ``name`` (see :data:`MOTOR_LIMITS`)."""
    return _preset(MOTOR_LIMITS, name, "AK-series motor")


def limits_for_firmware(name: str) -> AK60Limits:
    """The :class:`AK60Limits` preset called ``name`` (see :data:`FIRMWARE_LIMITS`)."""
    return _preset(FIRMWARE_LIMITS, name, "AK60 firmware variant")


def _preset(table: dict[str, AK60Limits], name: str, what: str) -> AK60Limits:
    try:
        return table[name]
    except KeyError:
        raise ParameterError(f"unknown {what} {name!r}; known: {', '.join(sorted(table))}") from None


def float_to_uint(value: float, low: float, high: float, bits: int) -> int:
    """Clamp ``value`` to [low, high] and map it onto an unsigned ``bits``-bit field (rounded).

    NaN is rejected: a NaN command must never reach the wire.
    """
    if math.isnan(value):
        raise ParameterError("cannot encode NaN into a motor command field")
    clamped = min(max(value, low), high)
    # Half-up rounding (not Python's half-to-even) so that exact midpoints, such as 0 in a symmetric
    # range, land on the upper code like the firmware's own conversion.
    return math.floor((clamped - low) * ((1 << bits) - 1) / (high - low) + 0.5)


@overload
def uint_to_float(code: int, low: float, high: float, bits: int) -> float: ...
@overload
def uint_to_float(
    code: NDArray[np.integer[Any]], low: float, high: float, bits: int
) -> NDArray[np.float64]: ...
def uint_to_float(code: Any, low: float, high: float, bits: int) -> Any:
    """Inverse of :func:`float_to_uint` (exact at the field's grid points).

    ``code`` may be an integer array: element-wise the same arithmetic, so the simulation and the
    store's grid filter (:mod:`bowden.store.sensor_grids`) decode as the driver does, bit for bit.
    """
    return low + code * (high - low) / ((1 << bits) - 1)


@dataclass(frozen=True, slots=True)
class MitCommand:
    """One MIT-mode command in SI units (output shaft)."""

    position_rad: float = 0.0
    velocity_rad_s: float = 0.0
    kp: float = 0.0
    kd: float = 0.0
    torque_nm: float = 0.0


def pack_command(command: MitCommand, limits: AK60Limits) -> bytes:
    """The 8 data bytes of a command frame (values outside the limits are clamped)."""
    p = float_to_uint(command.position_rad, -limits.position_rad, limits.position_rad, POSITION_BITS)
    v = float_to_uint(command.velocity_rad_s, -limits.velocity_rad_s, limits.velocity_rad_s,
                      VELOCITY_BITS)
    kp = float_to_uint(command.kp, 0.0, limits.kp_max, GAIN_BITS)
    kd = float_to_uint(command.kd, 0.0, limits.kd_max, GAIN_BITS)
    t = float_to_uint(command.torque_nm, -limits.torque_nm, limits.torque_nm, TORQUE_BITS)
    return bytes((
        p >> 8, p & 0xFF,
        v >> 4, ((v & 0xF) << 4) | (kp >> 8),
        kp & 0xFF,
        kd >> 4, ((kd & 0xF) << 4) | (t >> 8),
        t & 0xFF,
    ))


def unpack_command(data: bytes | bytearray, limits: AK60Limits) -> MitCommand:
    """Decode a command frame (what the motor does; used by the simulated peer).

    Raises
    ------
    MalformedFrameError
        If ``data`` is not 8 bytes or is a special frame.
    """
    if len(data) != 8:
        raise MalformedFrameError(f"AK60 command frame must have 8 data bytes, got {len(data)}")
    if bytes(data) in SPECIAL_FRAMES:
        raise MalformedFrameError("special frame passed to unpack_command")
    p = (data[0] << 8) | data[1]
    v = (data[2] << 4) | (data[3] >> 4)
    kp = ((data[3] & 0xF) << 8) | data[4]
    kd = (data[5] << 4) | (data[6] >> 4)
    t = ((data[6] & 0xF) << 8) | data[7]
    return MitCommand(
        position_rad=uint_to_float(p, -limits.position_rad, limits.position_rad, POSITION_BITS),
        velocity_rad_s=uint_to_float(v, -limits.velocity_rad_s, limits.velocity_rad_s, VELOCITY_BITS),
        kp=uint_to_float(kp, 0.0, limits.kp_max, GAIN_BITS),
        kd=uint_to_float(kd, 0.0, limits.kd_max, GAIN_BITS),
        torque_nm=uint_to_float(t, -limits.torque_nm, limits.torque_nm, TORQUE_BITS),
    )


@dataclass(frozen=True, slots=True)
class MitReply:
    """One decoded reply, output-shaft units, position within ±limits (not yet unwrapped).

    ``temperature_c`` is NaN and ``error_code`` 0 for 6-byte replies (older firmware sends neither).
    """

    motor_id: int
    position_rad: float
    velocity_rad_s: float
    torque_nm: float
    temperature_c: float
    error_code: int


def pack_reply(reply: MitReply, limits: AK60Limits, *, length: int = 8) -> bytes:
    """Encode a reply frame of ``length`` 6 or 8 bytes (what the motor sends; used by the peer)."""
    if length not in (6, 8):
        raise ParameterError(f"AK60 reply length must be 6 or 8, got {length}")
    if not 0 <= reply.motor_id <= 0xFF:
        raise ParameterError(f"motor_id must fit one byte, got {reply.motor_id}")
    p = float_to_uint(reply.position_rad, -limits.position_rad, limits.position_rad, POSITION_BITS)
    v = float_to_uint(reply.velocity_rad_s, -limits.velocity_rad_s, limits.velocity_rad_s,
                      VELOCITY_BITS)
    t = float_to_uint(reply.torque_nm, -limits.torque_nm, limits.torque_nm, TORQUE_BITS)
    data = bytes((reply.motor_id, p >> 8, p & 0xFF, v >> 4, ((v & 0xF) << 4) | (t >> 8), t & 0xFF))
    if length == 6:
        return data
    temperature = 0.0 if math.isnan(reply.temperature_c) else reply.temperature_c
    raw_temperature = math.floor(
        (temperature - limits.temperature_offset_c) / limits.temperature_scale_c + 0.5
    )
    return data + bytes((min(max(raw_temperature, 0), 0xFF), reply.error_code & 0xFF))


def unpack_reply(data: bytes | bytearray, limits: AK60Limits) -> MitReply:
    """Decode a 6- or 8-byte reply frame.

    Any byte string either decodes to finite values inside the limits or raises
    :class:`~bowden.errors.MalformedFrameError`; nothing else escapes (fuzz-tested).
    """
    if len(data) not in (6, 8):
        raise MalformedFrameError(f"AK60 reply must have 6 or 8 data bytes, got {len(data)}")
    p = (data[1] << 8) | data[2]
    v = (data[3] << 4) | (data[4] >> 4)
    t = ((data[4] & 0xF) << 8) | data[5]
    if len(data) == 8:
        temperature = limits.temperature_offset_c + limits.temperature_scale_c * data[6]
        error_code = data[7]
    else:
        temperature, error_code = math.nan, 0
    return MitReply(
        motor_id=data[0],
        position_rad=uint_to_float(p, -limits.position_rad, limits.position_rad, POSITION_BITS),
        velocity_rad_s=uint_to_float(v, -limits.velocity_rad_s, limits.velocity_rad_s, VELOCITY_BITS),
        torque_nm=uint_to_float(t, -limits.torque_nm, limits.torque_nm, TORQUE_BITS),
        temperature_c=temperature,
        error_code=error_code,
    )


def position_resolution_rad(limits: AK60Limits) -> float:
    """One least-significant bit of the position field (rad)."""
    return 2.0 * limits.position_rad / ((1 << POSITION_BITS) - 1)


def velocity_resolution_rad_s(limits: AK60Limits) -> float:
    """One least-significant bit of the velocity field (rad/s)."""
    return 2.0 * limits.velocity_rad_s / ((1 << VELOCITY_BITS) - 1)


def torque_resolution_nm(limits: AK60Limits) -> float:
    """One least-significant bit of the torque field (Nm)."""
    return 2.0 * limits.torque_nm / ((1 << TORQUE_BITS) - 1)
