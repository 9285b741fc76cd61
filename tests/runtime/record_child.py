"""Child process of the SIGKILL test: records deterministic rows until killed.

Row i has time_s = i·1 ms and every other column a known function of i, so the parent can check each
committed row exactly. After each commit it prints the number of committed rows (flushed). With a
second argument, the index of the newest row handed to the recorder is kept in that file (8 bytes,
memory-mapped, so it is current when the process is killed): the parent measures what was lost.
With a third, full chunks hold that many rows (small, so the test sees chunks merged).
"""

from __future__ import annotations

import mmap
import struct
import sys
import time
from pathlib import Path

from bowden.runtime.recorder import Recorder, TrialInfo
from bowden.store.sample_chunks import CHUNK_ROWS


def row(i: int) -> tuple[float | int, ...]:
    t = i * 1e-3
    return (t, 0.1 * t, 0.2 * t, 0.3, 10.0 + i % 7, 0.05, 0.5 * (i % 3), 0.25, -1.0, float("nan"), 1, i % 4)


def main(path: str, progress: str | None = None, chunk_rows: int = CHUNK_ROWS) -> None:
    newest = None
    if progress is not None:
        Path(progress).write_bytes(struct.pack("<q", -1))
        with open(progress, "r+b") as file:
            newest = mmap.mmap(file.fileno(), 8)
    recorder = Recorder(
        path,
        TrialInfo(participant="P01", condition="support_50", speed="V2", support=0.5,
                  metadata={"rate_hz": 1000}),
        commit_interval_s=0.05,
        on_commit=lambda n: print(f"committed {n}", flush=True),
        chunk_rows=chunk_rows,
    )
    recorder.start()
    i = 0
    next_s = time.monotonic()
    while True:  # until SIGKILL
        recorder.record(row(i))
        if newest is not None:
            struct.pack_into("<q", newest, 0, i)
        i += 1
        next_s += 1e-3
        delay = next_s - time.monotonic()
        if delay > 0:
            time.sleep(delay)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else None,
         int(sys.argv[3]) if len(sys.argv) > 3 else CHUNK_ROWS)
