"""Lossless compact encoding of a block of named numeric columns into one BLOB (the store's chunks).

Every value comes back bit for bit (NaN payloads included): nothing is rounded. Per column:

1. a filter that makes the stored numbers small or their neighbours' bits alike, chosen per column
   and named in the header (a filter is only used where it gives every value back exactly):

   - ``delta`` (integers): the difference from the previous value, wrapping, so a cumulative sum
     inverts it;
   - ``lpc`` (16-bit codes, compressed blocks): the residual of an exact integer linear prediction
     (:mod:`bowden.store.lpc`), about 6 % smaller than ``delta`` on sEMG;
   - ``grid`` (float64 readings of a sensor that reports integer codes, e.g. the AK60's 12-bit
     torque, the ADS1115's 16-bit load cell): the codes, delta-filtered, with the sensor's decode
     formula and parameters in the header (:mod:`bowden.store.sensor_grids`); NaN is one spare code;
   - ``f32xor`` (float64 values that are all exactly float32, e.g. the NGIMU's OSC floats): the
     float32 bits, XOR-ed with the previous value's;
   - ``xor`` (any other float): the XOR of the bits with the previous value's bits (sign, exponent
     and leading mantissa bits cancel for slowly varying signals);
2. the filtered values are split into byte planes (all first bytes, then all second bytes...): the
   high planes are nearly constant and compress well, the low planes of noisy signals are close to
   random;
3. each plane is compressed with zstd (pyarrow's, a core dependency) and kept raw where that does
   not make it smaller, so random planes cost neither space nor decompression time.

Blocks written with ``compress=False`` (the recorder's short-lived chunks) use ``xor``/``delta`` only:
the cheapest filters, as those blocks are merged and re-encoded soon. Blocks written before the
``lpc``, ``grid`` and ``f32xor`` filters existed name ``xor`` or ``delta`` and decode as before.
Measured on a simulated study: benchmarks/store.py.

Layout of a BLOB: the magic ``BWC1``, a little-endian uint32 header length, a UTF-8 JSON header
``{"rows": n, "columns": [{"name", "dtype", "filter", "planes": [[codec, stored bytes], ...], ...}]}``
(``codec`` ``"zstd"`` or ``"raw"``; ``grid`` adds ``"grid": {"formula", "params"}``, ``"codes"`` (the
codes' dtype) and ``"nan_code"`` (or null); ``lpc`` adds ``"lpc": {"shift", "coefficients"}``), then
the planes in header order.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Mapping, Sequence
from functools import cache
from typing import TYPE_CHECKING, Any, Final

import numpy as np

from bowden.errors import StoreError
from bowden.store.sensor_grids import Grid

if TYPE_CHECKING:
    import pyarrow as pa

MAGIC: Final = b"BWC1"
_LENGTH: Final = struct.Struct("<I")
# zstd level 3: within 1 % of level 19 on these planes at a hundredth of the time.
_ZSTD_LEVEL: Final = 3
# The dtypes a column may have, by their numpy string, with their basic filter; all little-endian.
_DTYPES: Final = {"<f8": "xor", "<f4": "xor", "<i8": "delta", "<i4": "delta", "<i2": "delta"}
_FILTERS: Final = frozenset({"xor", "delta", "f32xor", "grid", "lpc"})
_UNSIGNED: Final[dict[int, np.dtype[Any]]] = {8: np.dtype("<u8"), 4: np.dtype("<u4"), 2: np.dtype("<u2")}
_CODES: Final = np.dtype("<i2")  # every known grid's codes fit 16 bits (AK60 12-bit, ADS1115 16-bit)

Grids = Mapping[str, Sequence[Grid]]


@cache
def _zstd() -> pa.Codec:
    # pyarrow is imported on first use: the recorder starts without paying for it.
    import pyarrow as pa

    return pa.Codec("zstd", compression_level=_ZSTD_LEVEL)


def encode_columns(
    columns: Mapping[str, np.ndarray[Any, Any]], *, compress: bool = True, grids: Grids | None = None
) -> bytes:
    """One BLOB holding ``columns`` (equal lengths; float64/32 or int64/32/16), losslessly.

    ``compress=False`` keeps every byte plane raw and uses the cheapest filters: for the recorder's
    short-lived 0.1 s chunks, whose hundred tiny compressions per commit would hold the interpreter
    while the control loop waits. ``grids`` names, per column, the sensor grids to try (in order) for
    a float64 column: the first one that reproduces every value bit for bit is used.

    Raises
    ------
    StoreError
        A column of another dtype or length (names the column).
    """
    rows = -1
    header: list[dict[str, Any]] = []
    payload: list[bytes] = []
    for name, values in columns.items():
        array = np.asarray(values)
        dtype = array.dtype.newbyteorder("<") if array.dtype.byteorder == ">" else array.dtype
        code = dtype.str.replace("=", "<").replace("|", "<")
        if code not in _DTYPES or array.ndim != 1:
            raise StoreError(
                f"column {name!r}: cannot encode a {array.ndim}-d {array.dtype} array "
                f"(one-dimensional {', '.join(_DTYPES)} only)"
            )
        if rows < 0:
            rows = array.size
        elif array.size != rows:
            raise StoreError(f"column {name!r} has {array.size} values, the others {rows}")
        array = np.ascontiguousarray(array, dtype=code)
        entry: dict[str, Any] = {"name": name, "dtype": code}
        candidates = grids.get(name, ()) if grids is not None and compress else ()
        filtered = _filter_best(array, entry, candidates) if compress else _filter(array, _DTYPES[code])
        entry.setdefault("filter", _DTYPES[code])
        planes = []
        for plane in _planes(filtered):
            packed = _zstd().compress(plane, asbytes=True) if compress else plane
            if len(packed) < len(plane):
                planes.append(["zstd", len(packed)])
                payload.append(packed)
            else:
                planes.append(["raw", len(plane)])
                payload.append(plane)
        entry["planes"] = planes
        header.append(entry)
    text = json.dumps({"rows": max(rows, 0), "columns": header}, separators=(",", ":")).encode()
    return b"".join((MAGIC, _LENGTH.pack(len(text)), text, *payload))


def decode_columns(blob: bytes) -> dict[str, np.ndarray[Any, Any]]:
    """The columns of a BLOB made by :func:`encode_columns`, bit for bit.

    Raises
    ------
    StoreError
        The BLOB is not of this format, is truncated or names an unknown dtype, filter or grid.
    """
    view = memoryview(blob)
    header, offset = _header(view)
    try:
        rows = int(header["rows"])
        columns: dict[str, np.ndarray[Any, Any]] = {}
        for column in header["columns"]:
            if column["dtype"] not in _DTYPES:
                raise StoreError(f"a stored chunk has a column of unknown dtype {column['dtype']!r}")
            if column["filter"] not in _FILTERS:
                raise StoreError(f"a stored chunk uses an unknown filter {column['filter']!r}")
            dtype = np.dtype(column["dtype"])
            stored = _stored_dtype(column, dtype)
            planes = []
            for codec, size in column["planes"]:
                data = view[offset : offset + size]
                if len(data) != size:
                    raise StoreError("a stored chunk is truncated")
                offset += size
                if codec not in ("zstd", "raw"):
                    raise StoreError(f"a stored chunk uses an unknown compression {codec!r}")
                planes.append(
                    _zstd().decompress(data, decompressed_size=rows, asbytes=True)
                    if codec == "zstd"
                    else bytes(data)
                )
            columns[column["name"]] = _unfilter(_join(planes, stored, rows), column, dtype)
    except (KeyError, TypeError, ValueError, OSError) as error:  # pyarrow raises OSError subclasses
        raise StoreError(f"a stored chunk cannot be decoded ({error})") from None
    return columns


def round_trip_problem(blob: bytes, columns: Mapping[str, np.ndarray[Any, Any]]) -> str | None:
    """Why ``blob`` does not give ``columns`` back bit for bit, or None when it does.

    The check before the values' other copy is deleted (the recorder's merge, a trial's encoding):
    a fault of the encoder then costs the space it would have saved, never the values.
    """
    try:
        decoded = decode_columns(blob)
    except StoreError as error:
        return str(error)
    if list(decoded) != list(columns):
        return f"it holds the columns {list(decoded)}, not {list(columns)}"
    for name, values in columns.items():
        array = np.asarray(values)
        expected = array.astype(array.dtype.newbyteorder("<"), copy=False)
        got = decoded[name]
        if got.dtype != expected.dtype or got.shape != expected.shape:
            return (f"column {name!r} comes back as {got.size} {got.dtype} values, "
                    f"not {expected.size} {expected.dtype}")
        unsigned = _UNSIGNED.get(expected.itemsize)
        if unsigned is None:  # a dtype of no other size is ever encoded
            return f"column {name!r} has an item size of {expected.itemsize} bytes"
        bits, want = got.view(unsigned), np.ascontiguousarray(expected).view(unsigned)
        if not np.array_equal(bits, want):
            row = int(np.flatnonzero(bits != want)[0])
            return f"column {name!r} differs from row {row} ({got[row]!r} instead of {expected[row]!r})"
    return None


def column_sizes(blob: bytes) -> dict[str, tuple[str, int]]:
    """Per column of a BLOB: its filter and its stored bytes (for size breakdowns).

    Raises
    ------
    StoreError
        The BLOB is not of this format.
    """
    header, _ = _header(memoryview(blob))
    try:
        return {str(c["name"]): (str(c["filter"]), sum(int(size) for _codec, size in c["planes"]))
                for c in header["columns"]}
    except (KeyError, TypeError, ValueError) as error:
        raise StoreError(f"a stored chunk's header cannot be read ({error})") from None


def _header(view: memoryview) -> tuple[dict[str, Any], int]:
    """A BLOB's JSON header and the offset of its first plane."""
    if bytes(view[:4]) != MAGIC or len(view) < 8:
        raise StoreError("a stored chunk is not in bowden's column format (BWC1)")
    (length,) = _LENGTH.unpack(view[4:8])
    try:
        header = json.loads(bytes(view[8 : 8 + length]))
    except ValueError as error:
        raise StoreError(f"a stored chunk's header cannot be read ({error})") from None
    if not isinstance(header, dict):
        raise StoreError("a stored chunk's header is not an object")
    return header, 8 + length


def _stored_dtype(column: Mapping[str, Any], dtype: np.dtype[Any]) -> np.dtype[Any]:
    """The dtype of the filtered values a column's planes hold."""
    if column["filter"] == "f32xor":
        return np.dtype("<f4")
    if column["filter"] == "grid":
        if column["codes"] != _CODES.str:
            raise StoreError(f"a stored chunk has grid codes of unknown dtype {column['codes']!r}")
        return _CODES
    return dtype


def _filter_best(
    array: np.ndarray[Any, Any], entry: dict[str, Any], grids: Sequence[Grid]
) -> np.ndarray[Any, Any]:
    """The filtered values of the best exact filter for ``array``; its name and data go to ``entry``."""
    if array.dtype == np.float64 and array.size:
        for grid in grids:
            codes = _grid_codes(array, grid)
            if codes is not None:
                codes_out, nan_code = codes
                entry.update(filter="grid", grid=grid.header(), codes=_CODES.str, nan_code=nan_code)
                return _filter(codes_out, "delta")
        with np.errstate(over="ignore"):  # a value beyond float32's range is simply not float32
            narrow = array.astype(np.float32)
        if np.array_equal(narrow.astype(np.float64).view(np.uint64), array.view(np.uint64)):
            entry["filter"] = "f32xor"
            return _filter(narrow, "xor")
    if array.dtype == np.int16:
        from bowden.store import lpc  # numba: only where a block has 16-bit codes

        coefficients = lpc.fit(array)
        if coefficients is not None:
            entry.update(filter="lpc", lpc={"shift": lpc.SHIFT, "coefficients": coefficients.tolist()})
            return lpc.residual(array, coefficients, lpc.SHIFT)
    return _filter(array, _DTYPES[array.dtype.str])


def _grid_codes(values: np.ndarray[Any, Any], grid: Grid) -> tuple[np.ndarray[Any, Any], int | None] | None:
    """The int16 codes of ``values`` on ``grid`` (NaN as a spare code), or None unless they give
    every value back bit for bit."""
    info = np.iinfo(_CODES)
    head = values[:16]
    head = head[~np.isnan(head)]
    probe = grid.nearest_codes(head)
    if not (np.all((probe >= info.min) & (probe <= info.max))
            and _same_bits(grid.decode(probe.astype(_CODES)), head)):
        return None  # a wrong grid is mostly rejected on a few values
    nearest = grid.nearest_codes(values)
    missing = np.isnan(nearest)
    present = nearest[~missing]
    if not present.size:
        return None  # all missing: xor stores that in almost nothing
    low, high = float(present.min()), float(present.max())
    if low < info.min or high > info.max:
        return None
    nan_code: int | None = None
    if missing.any():
        nan_code = int(low) - 1 if low - 1 >= info.min else int(high) + 1
        if nan_code > info.max:
            return None
        nearest[missing] = nan_code
    codes = nearest.astype(_CODES)
    if not _same_bits(_grid_values(grid, codes, nan_code), values):
        return None
    return codes, nan_code


def _same_bits(a: np.ndarray[Any, Any], b: np.ndarray[Any, Any]) -> bool:
    """Equal bit for bit (so NaN payloads and the sign of zero count)."""
    return bool(np.array_equal(a.view(np.uint64), b.view(np.uint64)))


def _grid_values(grid: Grid, codes: np.ndarray[Any, Any], nan_code: int | None) -> np.ndarray[Any, Any]:
    values = grid.decode(codes)
    if nan_code is not None:
        values[codes == nan_code] = np.nan
    return values


def _filter(array: np.ndarray[Any, Any], kind: str) -> np.ndarray[Any, Any]:
    bits = array.view(_UNSIGNED[array.itemsize]) if kind == "xor" else array
    out = bits.copy()
    if kind == "xor":
        np.bitwise_xor(bits[1:], bits[:-1], out=out[1:])
    else:
        np.subtract(bits[1:], bits[:-1], out=out[1:])  # integer arrays wrap, as the sum undoes
    return out


def _unfilter(
    filtered: np.ndarray[Any, Any], column: Mapping[str, Any], dtype: np.dtype[Any]
) -> np.ndarray[Any, Any]:
    kind = column["filter"]
    if kind == "xor":
        return np.bitwise_xor.accumulate(filtered.view(_UNSIGNED[dtype.itemsize])).view(dtype)
    if kind == "delta":
        return np.cumsum(filtered.view(dtype), dtype=dtype)
    if kind == "f32xor":
        if dtype != np.float64:
            raise StoreError(f"a stored chunk has an f32xor column of dtype {dtype.str}")
        narrow = np.bitwise_xor.accumulate(filtered.view(np.uint32)).view(np.float32)
        return narrow.astype(np.float64)
    if kind == "grid":
        if dtype != np.float64:
            raise StoreError(f"a stored chunk has a grid column of dtype {dtype.str}")
        codes = np.cumsum(filtered.view(_CODES), dtype=_CODES)
        nan_code = None if column["nan_code"] is None else int(column["nan_code"])
        return _grid_values(Grid.from_header(column["grid"]), codes, nan_code)
    if kind == "lpc":
        if dtype not in (np.dtype("<i2"), np.dtype("<i4")):
            raise StoreError(f"a stored chunk has an lpc column of dtype {dtype.str}")
        from bowden.store import lpc

        spec = column["lpc"]
        coefficients = np.asarray(spec["coefficients"], dtype=np.int64)
        shift = int(spec["shift"])
        if coefficients.ndim != 1 or not 0 <= shift < 32:
            raise StoreError("a stored chunk has malformed lpc coefficients")
        return lpc.restore(filtered.view(dtype), coefficients, shift)
    raise StoreError(f"a stored chunk uses an unknown filter {kind!r}")


def _planes(filtered: np.ndarray[Any, Any]) -> list[bytes]:
    as_bytes = filtered.view(np.uint8).reshape(-1, filtered.itemsize)
    return [as_bytes[:, i].tobytes() for i in range(filtered.itemsize)]


def _join(planes: list[bytes], dtype: np.dtype[Any], rows: int) -> np.ndarray[Any, Any]:
    if len(planes) != dtype.itemsize or any(len(p) != rows for p in planes):
        raise StoreError("a stored chunk's planes do not match its header")
    as_bytes = np.empty((rows, dtype.itemsize), dtype=np.uint8)
    for i, plane in enumerate(planes):
        as_bytes[:, i] = np.frombuffer(plane, dtype=np.uint8)
    return as_bytes.reshape(-1).view(dtype)
