"""Lossless compact encoding of a block of named numeric columns into one BLOB (the store's chunks).

Every value comes back bit for bit (NaN payloads included): nothing is rounded. Per column:

1. a filter that makes neighbouring samples' bits alike: integers are replaced by their difference
   from the previous value (wrapping, so it inverts exactly by a cumulative sum); floats by the XOR
   of their bits with the previous value's bits (sign, exponent and leading mantissa bits cancel
   for slowly varying signals);
2. the filtered values are split into byte planes (all first bytes, then all second bytes...): the
   high planes are nearly constant and compress well, the low planes of noisy signals are close to
   random;
3. each plane is compressed with zstd (pyarrow's, a core dependency) and kept raw where that does
   not make it smaller, so random planes cost neither space nor decompression time.

Measured on a simulated study (benchmarks/store.py): float64 control samples to about 41 % of their
bytes (the low mantissa bytes of sensor noise are incompressible), 16-bit EMG codes to about 85 %.

Layout of a BLOB: the magic ``BWC1``, a little-endian uint32 header length, a UTF-8 JSON header
``{"rows": n, "columns": [{"name", "dtype", "filter", "planes": [[codec, stored bytes], ...]}]}``
(``codec`` ``"zstd"`` or ``"raw"``), then the planes in header order.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Mapping
from functools import cache
from typing import TYPE_CHECKING, Any, Final

import numpy as np

from bowden.errors import StoreError

if TYPE_CHECKING:
    import pyarrow as pa

MAGIC: Final = b"BWC1"
_LENGTH: Final = struct.Struct("<I")
# zstd level 3: within 1 % of level 19 on these planes at a hundredth of the time.
_ZSTD_LEVEL: Final = 3
# The dtypes a column may have, by their numpy string; all little-endian whatever the host.
_DTYPES: Final = {"<f8": "xor", "<f4": "xor", "<i8": "delta", "<i4": "delta", "<i2": "delta"}
_UNSIGNED: Final[dict[int, np.dtype[Any]]] = {8: np.dtype("<u8"), 4: np.dtype("<u4"), 2: np.dtype("<u2")}


@cache
def _zstd() -> pa.Codec:
    # pyarrow is imported on first use: the recorder starts without paying for it.
    import pyarrow as pa

    return pa.Codec("zstd", compression_level=_ZSTD_LEVEL)


def encode_columns(columns: Mapping[str, np.ndarray[Any, Any]], *, compress: bool = True) -> bytes:
    """One BLOB holding ``columns`` (equal lengths; float64/32 or int64/32/16), losslessly.

    ``compress=False`` keeps every byte plane raw: for the recorder's short-lived 0.1 s chunks, whose
    hundred tiny compressions per commit would hold the interpreter while the control loop waits.

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
        filtered = _filter(np.ascontiguousarray(array, dtype=code), _DTYPES[code])
        planes = []
        for plane in _planes(filtered):
            packed = _zstd().compress(plane, asbytes=True) if compress else plane
            if len(packed) < len(plane):
                planes.append(["zstd", len(packed)])
                payload.append(packed)
            else:
                planes.append(["raw", len(plane)])
                payload.append(plane)
        header.append({"name": name, "dtype": code, "filter": _DTYPES[code], "planes": planes})
    text = json.dumps({"rows": max(rows, 0), "columns": header}, separators=(",", ":")).encode()
    return b"".join((MAGIC, _LENGTH.pack(len(text)), text, *payload))


def decode_columns(blob: bytes) -> dict[str, np.ndarray[Any, Any]]:
    """The columns of a BLOB made by :func:`encode_columns`, bit for bit.

    Raises
    ------
    StoreError
        The BLOB is not of this format or is truncated.
    """
    view = memoryview(blob)
    if bytes(view[:4]) != MAGIC or len(view) < 8:
        raise StoreError("a stored chunk is not in bowden's column format (BWC1)")
    (length,) = _LENGTH.unpack(view[4:8])
    try:
        header = json.loads(bytes(view[8 : 8 + length]))
        rows = int(header["rows"])
        offset = 8 + length
        columns: dict[str, np.ndarray[Any, Any]] = {}
        for column in header["columns"]:
            if column["dtype"] not in _DTYPES:
                raise StoreError(f"a stored chunk has a column of unknown dtype {column['dtype']!r}")
            dtype = np.dtype(column["dtype"])
            planes = []
            for codec, size in column["planes"]:
                stored = view[offset : offset + size]
                if len(stored) != size:
                    raise StoreError("a stored chunk is truncated")
                offset += size
                if codec not in ("zstd", "raw"):
                    raise StoreError(f"a stored chunk uses an unknown compression {codec!r}")
                planes.append(
                    _zstd().decompress(stored, decompressed_size=rows, asbytes=True)
                    if codec == "zstd"
                    else bytes(stored)
                )
            columns[column["name"]] = _unfilter(_join(planes, dtype, rows), column["filter"], dtype)
    except (KeyError, TypeError, ValueError, OSError) as error:  # pyarrow raises OSError subclasses
        raise StoreError(f"a stored chunk cannot be decoded ({error})") from None
    return columns


def _filter(array: np.ndarray[Any, Any], kind: str) -> np.ndarray[Any, Any]:
    bits = array.view(_UNSIGNED[array.itemsize]) if kind == "xor" else array
    out = bits.copy()
    if kind == "xor":
        np.bitwise_xor(bits[1:], bits[:-1], out=out[1:])
    else:
        np.subtract(bits[1:], bits[:-1], out=out[1:])  # integer arrays wrap, as the sum undoes
    return out


def _unfilter(filtered: np.ndarray[Any, Any], kind: str, dtype: np.dtype[Any]) -> np.ndarray[Any, Any]:
    if kind == "xor":
        return np.bitwise_xor.accumulate(filtered.view(_UNSIGNED[dtype.itemsize])).view(dtype)
    if kind == "delta":
        return np.cumsum(filtered.view(dtype), dtype=dtype)
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
    return as_bytes.reshape(-1)

