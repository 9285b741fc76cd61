"""AK60-6 MIT-mode frames: hand-derived bytes, round trips, and fuzzing of every parser."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bowden.errors import MalformedFrameError, ParameterError
from bowden.hardware.ak60_codec import (
    ENTER_MOTOR_MODE,
    EXIT_MOTOR_MODE,
    FIRMWARE_LIMITS,
    SET_ZERO,
    SPECIAL_FRAMES,
    AK60Limits,
    MitCommand,
    MitReply,
    MotorErrorCode,
    float_to_uint,
    limits_for_firmware,
    pack_command,
    pack_reply,
    position_resolution_rad,
    torque_resolution_nm,
    uint_to_float,
    unpack_command,
    unpack_reply,
    velocity_resolution_rad_s,
)

MANUAL = FIRMWARE_LIMITS["manual-v1.0.8"]
PEAK = FIRMWARE_LIMITS["peak-9nm"]


def test_special_frames_are_the_manuals() -> None:
    assert ENTER_MOTOR_MODE.hex() == "fffffffffffffffc"
    assert EXIT_MOTOR_MODE.hex() == "fffffffffffffffd"
    assert SET_ZERO.hex() == "fffffffffffffffe"


def test_zero_command_bytes_by_hand() -> None:
    # p: 12.5·65535/25 = 32767.5 → 32768 = 0x8000; v: 45·4095/90 = 2047.5 → 0x800; t likewise 0x800.
    assert pack_command(MitCommand(), MANUAL).hex() == "8000800000000800"


def test_extreme_command_bytes_by_hand() -> None:
    # p = +P → 0xFFFF; v = −V → 0x000; Kp = 500 → 0xFFF; Kd = 5 → 0xFFF; t = +T → 0xFFF.
    command = MitCommand(position_rad=12.5, velocity_rad_s=-45.0, kp=500.0, kd=5.0, torque_nm=15.0)
    assert pack_command(command, MANUAL).hex() == "ffff000fffffffff"


def test_torque_field_by_hand_and_the_byte_6_layout() -> None:
    # t = 1 Nm: (1 + 15)·4095/30 = 2184 = 0x888 exactly. Kd = 5 sets byte 5 = 0xFF and byte 6's high
    # nibble: byte 6 = Kd[3:0] << 4 | t[11:8] (the manual's table, not its sample code).
    command = MitCommand(kd=5.0, torque_nm=1.0)
    data = pack_command(command, MANUAL)
    assert data[5] == 0xFF
    assert data[6] == 0xF8
    assert data[7] == 0x88


def test_torque_range_depends_on_firmware_variant() -> None:
    # The same 2 Nm is a different code on the two variants: a wrong range silently rescales torque.
    manual = pack_command(MitCommand(torque_nm=2.0), MANUAL)
    peak = pack_command(MitCommand(torque_nm=2.0), PEAK)
    assert manual != peak
    misread = unpack_command(peak, MANUAL).torque_nm
    assert misread == pytest.approx(2.0 * 15.0 / 9.0, abs=2 * torque_resolution_nm(MANUAL))


def test_values_outside_the_range_are_clamped() -> None:
    assert unpack_command(pack_command(MitCommand(torque_nm=100.0), MANUAL), MANUAL).torque_nm == 15.0
    assert unpack_command(pack_command(MitCommand(torque_nm=-100.0), MANUAL), MANUAL).torque_nm == -15.0


def test_nan_never_reaches_the_wire() -> None:
    with pytest.raises(ParameterError, match="NaN"):
        pack_command(MitCommand(torque_nm=math.nan), MANUAL)


def test_reply_bytes_by_hand() -> None:
    reply = unpack_reply(bytes.fromhex("0180008008004b00"), MANUAL)
    assert reply.motor_id == 1
    assert reply.position_rad == pytest.approx(-12.5 + 32768 * 25.0 / 65535)
    assert reply.velocity_rad_s == pytest.approx(-45.0 + 2048 * 90.0 / 4095)
    assert reply.torque_nm == pytest.approx(-15.0 + 2048 * 30.0 / 4095)
    assert reply.temperature_c == 35.0  # 0x4B = 75, minus 40
    assert reply.error_code == 0


def test_six_byte_reply_has_no_temperature_or_error() -> None:
    reply = unpack_reply(bytes.fromhex("028000800800"), MANUAL)
    assert reply.motor_id == 2
    assert math.isnan(reply.temperature_c)
    assert reply.error_code == 0


@pytest.mark.parametrize("code", list(MotorErrorCode))
def test_each_error_code_is_decoded_and_named(code: MotorErrorCode) -> None:
    reply = unpack_reply(bytes([1, 0x80, 0, 0x80, 0x08, 0, 75, int(code)]), MANUAL)
    assert reply.error_code == code
    assert MotorErrorCode.describe(reply.error_code) == code.name.lower().replace("_", " ")


def test_unknown_error_code_is_named_not_rejected() -> None:
    assert MotorErrorCode.describe(42) == "unknown error code 42"


def test_limits_validation_and_presets() -> None:
    with pytest.raises(ParameterError, match="torque_nm"):
        AK60Limits(torque_nm=0.0)
    with pytest.raises(ParameterError, match="unknown AK60 firmware variant"):
        limits_for_firmware("v3")
    assert limits_for_firmware("peak-9nm").torque_nm == 9.0


@given(
    p=st.floats(-12.5, 12.5), v=st.floats(-45.0, 45.0), kp=st.floats(0.0, 500.0),
    kd=st.floats(0.0, 5.0), t=st.floats(-15.0, 15.0),
)
def test_command_round_trip_within_half_a_step(p: float, v: float, kp: float, kd: float, t: float) -> None:
    decoded = unpack_command(pack_command(MitCommand(p, v, kp, kd, t), MANUAL), MANUAL)
    assert abs(decoded.position_rad - p) <= position_resolution_rad(MANUAL) / 2 + 1e-12
    assert abs(decoded.velocity_rad_s - v) <= velocity_resolution_rad_s(MANUAL) / 2 + 1e-12
    assert abs(decoded.kp - kp) <= 500.0 / 4095 / 2 + 1e-12
    assert abs(decoded.kd - kd) <= 5.0 / 4095 / 2 + 1e-12
    assert abs(decoded.torque_nm - t) <= torque_resolution_nm(MANUAL) / 2 + 1e-12


@given(st.binary(min_size=8, max_size=8))
def test_command_bytes_round_trip_exactly(data: bytes) -> None:
    if data in SPECIAL_FRAMES:
        with pytest.raises(MalformedFrameError):
            unpack_command(data, MANUAL)
        return
    assert pack_command(unpack_command(data, PEAK), PEAK) == data


@given(st.binary(min_size=8, max_size=8))
def test_eight_byte_reply_round_trips_exactly(data: bytes) -> None:
    assert pack_reply(unpack_reply(data, MANUAL), MANUAL, length=8) == data


@given(st.binary(min_size=6, max_size=6))
def test_six_byte_reply_round_trips_exactly(data: bytes) -> None:
    assert pack_reply(unpack_reply(data, PEAK), PEAK, length=6) == data


@given(st.integers(0, 0xFF), st.floats(-12.5, 12.5), st.floats(-45, 45), st.floats(-15, 15),
       st.integers(0, 6))
def test_reply_value_round_trip(motor_id: int, p: float, v: float, t: float, code: int) -> None:
    reply = unpack_reply(pack_reply(MitReply(motor_id, p, v, t, 41.0, code), MANUAL), MANUAL)
    assert reply.motor_id == motor_id and reply.error_code == code and reply.temperature_c == 41.0
    assert abs(reply.position_rad - p) <= position_resolution_rad(MANUAL) / 2 + 1e-12
    assert abs(reply.torque_nm - t) <= torque_resolution_nm(MANUAL) / 2 + 1e-12


@given(st.binary(max_size=16))
def test_random_bytes_never_crash_the_reply_parser(data: bytes) -> None:
    try:
        reply = unpack_reply(data, MANUAL)
    except MalformedFrameError:
        assert len(data) not in (6, 8)
        return
    for value, bound in ((reply.position_rad, 12.5), (reply.velocity_rad_s, 45.0), (reply.torque_nm, 15.0)):
        assert math.isfinite(value) and -bound <= value <= bound
    assert 0 <= reply.error_code <= 255


@given(st.binary(max_size=16))
def test_random_bytes_never_crash_the_command_parser(data: bytes) -> None:
    try:
        command = unpack_command(data, MANUAL)
    except MalformedFrameError:
        assert len(data) != 8 or data in SPECIAL_FRAMES
        return
    assert 0.0 <= command.kp <= 500.0 and 0.0 <= command.kd <= 5.0
    assert -15.0 <= command.torque_nm <= 15.0


@given(st.integers(0, 4095))
def test_field_mapping_is_exact_at_grid_points(code: int) -> None:
    assert float_to_uint(uint_to_float(code, -15.0, 15.0, 12), -15.0, 15.0, 12) == code
