"""A minimal XDF 1.0 writer, written from the specification (sccn/xdf wiki, "Specifications").

File: the magic ``XDF:``, then chunks ``[NumLengthBytes][Length][Tag u16][Content]`` where Length
counts tag and content. Tags used: 1 FileHeader (XML), 2 StreamHeader (u32 stream id + XML),
3 Samples (u32 stream id, variable-length sample count, then per sample ``[TimeStampBytes 0|8]
[f64 stamp][values]``; strings as variable-length byte count + bytes), 4 ClockOffset (u32 id,
f64 collection time, f64 offset), 6 StreamFooter (u32 id + XML). Little-endian throughout.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np


def _varlen(n: int) -> bytes:
    if n < 256:
        return b"\x01" + struct.pack("<B", n)
    if n < 2**32:
        return b"\x04" + struct.pack("<I", n)
    return b"\x08" + struct.pack("<Q", n)


def _chunk(tag: int, content: bytes) -> bytes:
    return _varlen(len(content) + 2) + struct.pack("<H", tag) + content


class XdfWriter:
    """Streams declared up front, then sample chunks, then footers; ``close()`` writes the file."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._parts = [b"XDF:", _chunk(1, b'<?xml version="1.0"?><info><version>1.0</version></info>')]
        self._stamps: dict[int, list[float]] = {}

    def stream(
        self,
        stream_id: int,
        *,
        name: str,
        kind: str,
        source_id: str,
        channel_format: str,
        nominal_srate: float,
        labels: Sequence[str],
        unit: str = "",
    ) -> None:
        channels = "".join(
            f"<channel><label>{escape(label)}</label><unit>{escape(unit)}</unit><type>{escape(kind)}</type>"
            "</channel>"
            for label in labels
        )
        xml = (
            '<?xml version="1.0"?><info>'
            f"<name>{escape(name)}</name><type>{escape(kind)}</type><channel_count>{len(labels)}</channel_count>"
            f"<nominal_srate>{nominal_srate!r}</nominal_srate><channel_format>{channel_format}</channel_format>"
            f"<source_id>{escape(source_id)}</source_id><created_at>0</created_at>"
            f"<desc><channels>{channels}</channels></desc></info>"
        )
        self._parts.append(_chunk(2, struct.pack("<I", stream_id) + xml.encode()))
        self._stamps[stream_id] = []

    def numeric_samples(self, stream_id: int, stamps: np.ndarray, values: np.ndarray) -> None:
        """float64 samples (rows) with one time stamp each."""
        rows = np.asarray(values, dtype="<f8")
        body = bytearray(struct.pack("<I", stream_id) + _varlen(len(rows)))
        record = np.zeros(len(rows), dtype=[("n", "u1"), ("t", "<f8"), ("v", "<f8", (rows.shape[1],))])
        record["n"], record["t"], record["v"] = 8, stamps, rows
        body += record.tobytes()
        self._parts.append(_chunk(3, bytes(body)))
        self._stamps[stream_id].extend((float(stamps[0]), float(stamps[-1])))

    def string_samples(self, stream_id: int, samples: Sequence[tuple[float, str]]) -> None:
        body = bytearray(struct.pack("<I", stream_id) + _varlen(len(samples)))
        for stamp, text in samples:
            data = text.encode()
            body += b"\x08" + struct.pack("<d", stamp) + _varlen(len(data)) + data
        self._parts.append(_chunk(3, bytes(body)))
        self._stamps[stream_id].extend(stamp for stamp, _ in samples)

    def clock_offset(self, stream_id: int, collection_time: float, offset: float) -> None:
        self._parts.append(_chunk(4, struct.pack("<Idd", stream_id, collection_time, offset)))

    def close(self, sample_counts: dict[int, int]) -> None:
        for stream_id, stamps in self._stamps.items():
            xml = (
                '<?xml version="1.0"?><info>'
                f"<first_timestamp>{min(stamps)!r}</first_timestamp><last_timestamp>{max(stamps)!r}</last_timestamp>"
                f"<sample_count>{sample_counts[stream_id]}</sample_count></info>"
            )
            self._parts.append(_chunk(6, struct.pack("<I", stream_id) + xml.encode()))
        self.path.write_bytes(b"".join(self._parts))
