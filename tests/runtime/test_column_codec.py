"""The column codec: every value back bit for bit, whatever it is; bad input is a StoreError."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from bowden.errors import StoreError
from bowden.store.column_codec import decode_columns, encode_columns

DTYPES = ("<f8", "<f4", "<i8", "<i4", "<i2")


@settings(max_examples=60, deadline=None)
@given(
    st.integers(min_value=0, max_value=300).flatmap(
        lambda n: st.tuples(*(hnp.arrays(np.dtype(code), n) for code in DTYPES))
    )
)
def test_any_values_come_back_bit_for_bit(arrays: tuple[np.ndarray, ...]) -> None:
    columns = {f"c{i}": a for i, a in enumerate(arrays)}  # NaN payloads, ±inf, -0.0, extremes
    back = decode_columns(encode_columns(columns))
    assert list(back) == list(columns)
    for name, values in columns.items():
        assert back[name].dtype == values.dtype.newbyteorder("=")
        assert back[name].tobytes() == values.tobytes()


def test_smooth_signals_and_codes_compress() -> None:
    t = np.arange(20000) * 0.002
    rng = np.random.default_rng(1)
    columns = {
        "time_s": t,
        "angle": np.sin(t) + rng.normal(0, 1e-3, t.size),
        "state": np.ones(t.size, dtype=np.int64),
        "emg": np.rint(rng.normal(0, 3000, t.size)).astype(np.int16),
        "missing": np.full(t.size, np.nan),
    }
    blob = encode_columns(columns)
    raw = sum(a.nbytes for a in columns.values())
    assert len(blob) < 0.4 * raw
    assert decode_columns(blob)["emg"].tobytes() == columns["emg"].tobytes()


def test_big_endian_input_is_stored_little_endian() -> None:
    values = np.arange(10, dtype=">f8") / 3
    back = decode_columns(encode_columns({"x": values}))["x"]
    np.testing.assert_array_equal(back, values)


@pytest.mark.parametrize(
    ("columns", "message"),
    [
        ({"x": np.array(["a", "b"])}, "column 'x': cannot encode"),
        ({"x": np.zeros((2, 2))}, "column 'x': cannot encode a 2-d"),
        ({"x": np.zeros(3), "y": np.zeros(4)}, "column 'y' has 4 values, the others 3"),
        ({"x": np.zeros(3, dtype=np.uint8)}, "cannot encode"),
    ],
)
def test_what_cannot_be_encoded_is_named(columns: dict[str, np.ndarray], message: str) -> None:
    with pytest.raises(StoreError, match=message):
        encode_columns(columns)


def test_a_damaged_blob_is_a_store_error() -> None:
    blob = encode_columns({"x": np.arange(1000, dtype=np.float64)})
    with pytest.raises(StoreError, match="not in bowden's column format"):
        decode_columns(b"SQLite" + blob)
    with pytest.raises(StoreError, match=r"truncated|cannot be decoded|do not match"):
        decode_columns(blob[:-10])


def test_uncompressed_blobs_round_trip_and_keep_every_plane_raw() -> None:
    columns = {"time_s": np.arange(200) * 0.002, "state": np.full(200, 3, dtype=np.int64)}
    raw = encode_columns(columns, compress=False)
    packed = encode_columns(columns)
    assert len(packed) < len(raw)
    for blob in (raw, packed):
        back = decode_columns(blob)
        assert back["time_s"].tobytes() == columns["time_s"].tobytes()
        assert np.array_equal(back["state"], columns["state"])
    assert b'"zstd"' not in raw and b'"zstd"' in packed
