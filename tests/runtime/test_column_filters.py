"""The codec's filters: a hand-derived example each, bit-exact round trips (NaN payloads included),
the exactness checks that fall back to xor, and blobs written before these filters existed."""

from __future__ import annotations

import base64
import json
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from bowden.errors import StoreError
from bowden.hardware.ads1115 import LoadCellCalibration, conversion_to_volts, register_bytes
from bowden.hardware.ak60_codec import uint_to_float
from bowden.store import lpc
from bowden.store.column_codec import decode_columns, encode_columns
from bowden.store.sensor_grids import ADS1115, AK60, KNOWN_GRIDS, Grid

COEFFICIENT = st.integers(-(1 << 24) + 1, (1 << 24) - 1)  # what lpc.fit may store
TORQUE = Grid(AK60, (-15.0, 15.0, 12.0, 1.0))  # the AK60-6's torque field (manual V1.0.8)
LOAD_CELL = Grid(ADS1115, (4.096, 0.05, 100.0))  # the simulated suit's ADS1115 and calibration

# Written by the codec before the f32xor, grid and lpc filters (commit e7a1a1e): time_s, tension_n
# (NaN every fifth row), state (int64) and 16-bit codes, 12 rows, every plane raw.
OLD_BLOB = base64.b64decode(
    "QldDMSICAAB7InJvd3MiOjEyLCJjb2x1bW5zIjpbeyJuYW1lIjoidGltZV9zIiwiZHR5cGUiOiI8ZjgiLCJmaWx0ZXIiOiJ4"
    "b3IiLCJwbGFuZXMiOltbInJhdyIsMTJdLFsicmF3IiwxMl0sWyJyYXciLDEyXSxbInJhdyIsMTJdLFsicmF3IiwxMl0sWyJy"
    "YXciLDEyXSxbInJhdyIsMTJdLFsicmF3IiwxMl1dfSx7Im5hbWUiOiJ0ZW5zaW9uX24iLCJkdHlwZSI6IjxmOCIsImZpbHRl"
    "ciI6InhvciIsInBsYW5lcyI6W1sicmF3IiwxMl0sWyJyYXciLDEyXSxbInJhdyIsMTJdLFsicmF3IiwxMl0sWyJyYXciLDEy"
    "XSxbInJhdyIsMTJdLFsicmF3IiwxMl0sWyJyYXciLDEyXV19LHsibmFtZSI6InN0YXRlIiwiZHR5cGUiOiI8aTgiLCJmaWx0"
    "ZXIiOiJkZWx0YSIsInBsYW5lcyI6W1sicmF3IiwxMl0sWyJyYXciLDEyXSxbInJhdyIsMTJdLFsicmF3IiwxMl0sWyJyYXci"
    "LDEyXSxbInJhdyIsMTJdLFsicmF3IiwxMl0sWyJyYXciLDEyXV19LHsibmFtZSI6ImNvZGVzIiwiZHR5cGUiOiI8aTIiLCJm"
    "aWx0ZXIiOiJkZWx0YSIsInBsYW5lcyI6W1sicmF3IiwxMl0sWyJyYXciLDEyXV19XX0A/AAGBoeBg4XAR8EAqQDX171ql0B2"
    "y10A8QCbm1/ETNe+4aIA0gBubpX7jeNfykUATQA5OayVfEXadsoAYgDx8RjpP84MFP0AYBAI+AQMBBwCBgIAPwAAAAAAAAAA"
    "AAAA70lx0gVXIwy2zsoAtBss/n2jXSTDGeIAI6zJCkxfInARHO8AuV1mEJIJeTrcloUA/A4QKcuK1XHY9nMA/wAAAP//AAAB"
    "/v740AAAANDQAAAA0NB/PwAAAD8/AAAAPz8DAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA"
    "AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAARyPfgxeqRvbEtMoAAQEAAAD///7+"
    "/v4="
)


def old_columns() -> dict[str, np.ndarray]:
    t = np.arange(12) * 0.002
    return {
        "time_s": t,
        "tension_n": np.where(np.arange(12) % 5 == 0, np.nan, np.cos(t) * 12.5),
        "state": np.full(12, 3, dtype=np.int64),
        "codes": np.rint(1000 * np.sin(np.arange(12) / 3)).astype(np.int16),
    }


def header_and_planes(blob: bytes) -> tuple[dict, list[bytes]]:
    """The header, and every plane's stored bytes in order."""
    (length,) = struct.unpack("<I", blob[4:8])
    header = json.loads(blob[8 : 8 + length])
    planes, offset = [], 8 + length
    for column in header["columns"]:
        for _codec, size in column["planes"]:
            planes.append(blob[offset : offset + size])
            offset += size
    return header, planes


def filters(blob: bytes) -> dict[str, str]:
    return {c["name"]: c["filter"] for c in header_and_planes(blob)[0]["columns"]}


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.tobytes() == b.tobytes()


# --- old stores ------------------------------------------------------------------------------------
def test_a_blob_written_before_the_new_filters_decodes_as_before() -> None:
    assert filters(OLD_BLOB) == {"time_s": "xor", "tension_n": "xor", "state": "delta", "codes": "delta"}
    back = decode_columns(OLD_BLOB)
    for name, values in old_columns().items():
        assert same_bits(back[name], values), name


def test_uncompressed_blocks_keep_the_old_filters() -> None:
    # The recorder's 0.1 s chunks: the cheapest filters, readable by the old decoder's rules.
    codes = np.rint(1000 * np.sin(np.arange(500) / 5)).astype(np.int16)  # lpc when compressed
    columns = {"motor_torque_nm": TORQUE.decode(np.arange(1500, 2000)), "codes": codes}
    assert filters(encode_columns(columns, grids=KNOWN_GRIDS)) == {"motor_torque_nm": "grid", "codes": "lpc"}
    assert filters(encode_columns(columns, compress=False, grids=KNOWN_GRIDS)) == {
        "motor_torque_nm": "xor", "codes": "delta"}


# --- hand-derived examples, one per filter ---------------------------------------------------------
def test_xor_example() -> None:
    # 0.1 is 0x3FB999999999999A (not a float32); XOR-ed: itself, 0, then the sign bit alone.
    blob = encode_columns({"x": np.array([0.1, 0.1, -0.1])})
    assert filters(blob) == {"x": "xor"}
    planes = header_and_planes(blob)[1]
    assert planes[0] == bytes([0x9A, 0x00, 0x00]) and planes[7] == bytes([0x3F, 0x00, 0x80])
    assert planes[1:7] == [bytes([0x99, 0, 0])] * 5 + [bytes([0xB9, 0, 0])]


def test_delta_example() -> None:
    blob = encode_columns({"x": np.array([5, 7, 4], dtype=np.int64)})
    assert filters(blob) == {"x": "delta"}
    planes = header_and_planes(blob)[1]
    assert planes[0] == bytes([5, 2, 0xFD]) and planes[7] == bytes([0, 0, 0xFF])  # −3 wraps


def test_f32xor_example() -> None:
    # float32 bits 0x3F800000, 0x3FC00000, 0xC0000000; XOR-ed: 0x3F800000, 0x00400000, 0xFFC00000.
    blob = encode_columns({"imu": np.array([1.0, 1.5, -2.0])})
    header, planes = header_and_planes(blob)
    assert header["columns"][0]["filter"] == "f32xor" and len(planes) == 4
    assert planes == [bytes(3), bytes(3), bytes([0x80, 0x40, 0xC0]), bytes([0x3F, 0x00, 0xFF])]
    assert same_bits(decode_columns(blob)["imu"], np.array([1.0, 1.5, -2.0]))


def test_grid_example_ak60_torque_with_a_missing_value() -> None:
    # Codes 2048, 2050, 2047 on the ±15 Nm 12-bit field, then NaN: the spare code below them, 2046.
    values = np.array([uint_to_float(code, -15.0, 15.0, 12) for code in (2048, 2050, 2047)] + [np.nan])
    assert values[0] == -15.0 + 2048 * 30.0 / 4095
    blob = encode_columns({"motor_torque_nm": values}, grids={"motor_torque_nm": [TORQUE]})
    header, planes = header_and_planes(blob)
    column = header["columns"][0]
    assert column["filter"] == "grid" and column["codes"] == "<i2" and column["nan_code"] == 2046
    assert column["grid"] == {"formula": "ak60", "params": [-15.0, 15.0, 12.0, 1.0]}
    # Codes delta-filtered: 2048, +2, −3, −1 as little-endian int16 planes.
    assert planes == [bytes([0x00, 0x02, 0xFD, 0xFF]), bytes([0x08, 0x00, 0xFF, 0xFF])]
    assert same_bits(decode_columns(blob)["motor_torque_nm"], values)


def test_grid_example_ads1115_decodes_as_the_driver_reads_the_register() -> None:
    codes = [-5, 400, 401, 32767]
    calibration = LoadCellCalibration(offset_v=0.05, gain_n_per_v=100.0)
    values = np.array([calibration.tension_n(conversion_to_volts(register_bytes(c & 0xFFFF), 4.096))
                       for c in codes])
    blob = encode_columns({"tension_n": values}, grids=KNOWN_GRIDS)
    column = header_and_planes(blob)[0]["columns"][0]
    assert column["grid"] == {"formula": "ads1115", "params": [4.096, 0.05, 100.0]}
    assert same_bits(decode_columns(blob)["tension_n"], values)


def test_lpc_example() -> None:
    # pred = 2·x[i−1] − x[i−2] (coefficients in units of 2⁻¹²) predicts a ramp exactly; the first
    # sample stays, the second keeps its difference; a wrap past int16 inverts too.
    coefficients = np.array([2 << 12, -(1 << 12)], dtype=np.int64)
    ramp = np.array([10, 20, 30, 40, 50], dtype=np.int16)
    assert lpc.residual(ramp, coefficients, 12).tolist() == [10, 10, 0, 0, 0]
    wrapping = np.array([32767, -32768, 0, 5], dtype=np.int16)
    # −32768 − 32767 wraps to 1; 0 − (2·(−32768) − 32767 = −98303 → wraps to −32767) = 32767; ...
    residual = lpc.residual(wrapping, coefficients, 12)
    assert residual.tolist()[:3] == [32767, 1, 32767]
    for x in (ramp, wrapping):
        assert same_bits(lpc.restore(lpc.residual(x, coefficients, 12), coefficients, 12), x)


def test_lpc_is_chosen_for_16_bit_codes_and_beats_delta() -> None:
    rng = np.random.default_rng(3)
    e = rng.normal(0, 400, 20000)
    x = np.zeros(20000)
    for i in range(2, x.size):  # a resonant AR(2) process, like band-limited sEMG
        x[i] = 1.6 * x[i - 1] - 0.8 * x[i - 2] + e[i]
    codes = np.rint(x).astype(np.int16)
    blob = encode_columns({"codes": codes})
    assert filters(blob) == {"codes": "lpc"}
    assert same_bits(decode_columns(blob)["codes"], codes)
    assert len(blob) < 0.8 * len(encode_columns({"codes": codes.astype(np.int32)}))  # i4: delta


# --- exactness: round trips and fall-backs ---------------------------------------------------------
@settings(max_examples=80, deadline=None)
@given(
    hnp.arrays(np.int16, st.integers(1, 300), elements=st.integers(0, 4095)),
    st.lists(st.integers(0, 299), max_size=5),
    st.sampled_from(KNOWN_GRIDS["motor_torque_nm"] + KNOWN_GRIDS["motor_velocity_rad_s"]
                    + KNOWN_GRIDS["tension_n"]),
)
def test_values_on_a_grid_come_back_bit_for_bit(codes: np.ndarray, missing: list[int], grid: Grid) -> None:
    values = grid.decode(codes)
    values[[i for i in missing if i < values.size]] = np.nan
    name = "motor_torque_nm" if grid.formula == AK60 else "tension_n"
    blob = encode_columns({name: values}, grids={name: [grid]})
    assert same_bits(decode_columns(blob)[name], values)
    if np.isfinite(values).any():
        assert filters(blob)[name] == "grid"


@settings(max_examples=80, deadline=None)
@given(hnp.arrays(np.float64, st.integers(1, 300)))
def test_any_float64_with_grids_offered_comes_back_bit_for_bit(values: np.ndarray) -> None:
    # NaN payloads, ±inf, −0.0, values next to the grid: whatever is not exact falls back.
    for name in ("motor_torque_nm", "motor_velocity_rad_s", "tension_n"):
        assert same_bits(decode_columns(encode_columns({name: values}, grids=KNOWN_GRIDS))[name], values)


def test_a_value_one_ulp_off_the_grid_falls_back_to_xor() -> None:
    values = TORQUE.decode(np.arange(2000, 2100))
    values[50] = np.nextafter(values[50], np.inf)
    blob = encode_columns({"motor_torque_nm": values}, grids=KNOWN_GRIDS)
    assert filters(blob) == {"motor_torque_nm": "xor"}
    assert same_bits(decode_columns(blob)["motor_torque_nm"], values)


def test_a_nan_with_another_payload_falls_back_to_xor() -> None:
    values = TORQUE.decode(np.arange(2000, 2010))
    values[3] = np.frombuffer(struct.pack("<Q", 0x7FF8000000000001), dtype=np.float64)[0]
    blob = encode_columns({"motor_torque_nm": values}, grids=KNOWN_GRIDS)
    assert filters(blob) == {"motor_torque_nm": "xor"}
    assert same_bits(decode_columns(blob)["motor_torque_nm"], values)


@settings(max_examples=80, deadline=None)
@given(hnp.arrays(np.float32, st.integers(1, 300)))
def test_float32_values_come_back_bit_for_bit(narrow: np.ndarray) -> None:
    values = narrow.astype(np.float64)  # NaN payloads, ±inf, subnormals, −0.0
    blob = encode_columns({"imu": values})
    assert filters(blob) == {"imu": "f32xor"}
    assert same_bits(decode_columns(blob)["imu"], values)


@settings(max_examples=80, deadline=None)
@given(hnp.arrays(np.int16, st.integers(1, 400)))
def test_any_16_bit_codes_come_back_bit_for_bit(codes: np.ndarray) -> None:
    assert same_bits(decode_columns(encode_columns({"codes": codes}))["codes"], codes)


@settings(max_examples=40, deadline=None)
@given(
    hnp.arrays(np.int16, st.integers(1, 200)),
    hnp.arrays(np.int64, st.integers(1, 12), elements=COEFFICIENT),
    st.integers(0, 20),
)
def test_lpc_inverts_exactly_whatever_the_coefficients(codes: np.ndarray, coefficients: np.ndarray,
                                                       shift: int) -> None:
    assert same_bits(lpc.restore(lpc.residual(codes, coefficients, shift), coefficients, shift), codes)


def reference_residual(codes: np.ndarray, coefficients: np.ndarray, shift: int) -> np.ndarray:
    """The residual by its definition, with Python integers (an independent implementation)."""
    x = [int(v) for v in codes]
    out = []
    for i, value in enumerate(x):
        if i < len(coefficients):
            r = value if i == 0 else value - x[i - 1]
        else:
            r = value - (sum(int(c) * x[i - 1 - j] for j, c in enumerate(coefficients)) >> shift)
        out.append((r + 32768) % 65536 - 32768)
    return np.array(out, dtype=np.int16)


@settings(max_examples=40, deadline=None)
@given(
    hnp.arrays(np.int16, st.integers(1, 120)),
    hnp.arrays(np.int64, st.sampled_from([lpc.ORDER, 3]), elements=COEFFICIENT),
)
def test_lpc_residual_is_its_definition(codes: np.ndarray, coefficients: np.ndarray) -> None:
    # Order 8 runs the unrolled loops, order 3 the general ones.
    expected = reference_residual(codes, coefficients, lpc.SHIFT)
    assert same_bits(lpc.residual(codes, coefficients), expected)
    assert same_bits(lpc.restore(expected, coefficients), codes)


# --- damaged headers -------------------------------------------------------------------------------
def rewrite_header(blob: bytes, change: dict) -> bytes:
    (length,) = struct.unpack("<I", blob[4:8])
    header = json.loads(blob[8 : 8 + length])
    header["columns"][0].update(change)
    text = json.dumps(header).encode()
    return blob[:4] + struct.pack("<I", len(text)) + text + blob[8 + length :]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"filter": "zigzag"}, "unknown filter 'zigzag'"),
        ({"grid": {"formula": "ina219", "params": [1.0]}}, "unknown sensor grid formula 'ina219'"),
        ({"grid": {"formula": "ak60", "params": [1.0]}}, "needs 4 finite parameters"),
        ({"grid": {"formula": "ads1115", "params": [4.096, 0.05, 0.0]}}, "gain_n_per_v must be"),
        ({"codes": "<i8"}, "grid codes of unknown dtype"),
    ],
)
def test_a_damaged_grid_header_is_a_store_error(change: dict, message: str) -> None:
    values = TORQUE.decode(np.arange(2000, 2010))
    blob = encode_columns({"motor_torque_nm": values}, grids=KNOWN_GRIDS)
    with pytest.raises(StoreError, match=message):
        decode_columns(rewrite_header(blob, change))


def test_damaged_lpc_coefficients_are_a_store_error() -> None:
    codes = np.rint(1000 * np.sin(np.arange(500) / 5)).astype(np.int16)
    blob = encode_columns({"codes": codes})
    with pytest.raises(StoreError, match="malformed lpc"):
        decode_columns(rewrite_header(blob, {"lpc": {"shift": 99, "coefficients": [1]}}))
