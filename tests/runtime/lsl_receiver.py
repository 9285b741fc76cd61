"""Receive bowden's LSL streams with pylsl's own inlets (run as a separate process by the test).

Usage: python lsl_receiver.py OUT.json. Resolves the ``bowden markers`` and ``bowden loop`` streams
(resolve scope from $LSLAPICFG), opens both inlets, pulls until the trial-end marker has come and
no data has arrived for 1.5 s, then writes what it received as JSON.
"""

from __future__ import annotations

import json
import sys
import time

import pylsl


def _resolve(name: str) -> pylsl.StreamInfo:
    found = pylsl.resolve_byprop("name", name, minimum=1, timeout=120.0)
    if not found:
        raise SystemExit(f"stream {name!r} not found")
    return found[0]


def main() -> None:
    out = sys.argv[1]
    markers_info, loop_info = _resolve("bowden markers"), _resolve("bowden loop")
    markers = pylsl.StreamInlet(markers_info, max_buflen=360)
    loop = pylsl.StreamInlet(loop_info, max_buflen=360)
    markers.open_stream(timeout=60.0)
    loop.open_stream(timeout=60.0)
    received_markers: list[tuple[float, str]] = []
    samples: list[list[float]] = []
    stamps: list[float] = []
    ended_at = None
    last_data = time.monotonic()
    while True:
        chunk, chunk_stamps = loop.pull_chunk(timeout=0.05, max_samples=2000)
        if chunk:
            samples.extend(chunk)
            stamps.extend(chunk_stamps)
            last_data = time.monotonic()
        while True:
            sample, stamp = markers.pull_sample(timeout=0.0)
            if sample is None:
                break
            received_markers.append((stamp, sample[0]))
            last_data = time.monotonic()
            if json.loads(sample[0]).get("event") == "trial_end":
                ended_at = time.monotonic()
        if ended_at is not None and time.monotonic() - last_data > 1.5:
            break
    with open(out, "w", encoding="utf-8") as file:
        json.dump(
            {
                "markers": received_markers,
                "loop_times_s": [s[0] for s in samples],
                "stamps": stamps,
                "marker_source_id": markers_info.source_id(),
                "loop_source_id": loop_info.source_id(),
                "loop_rate_hz": loop_info.nominal_srate(),
                "loop_channels": loop_info.channel_count(),
            },
            file,
        )


if __name__ == "__main__":
    main()
