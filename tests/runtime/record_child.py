"""Child process of the SIGKILL test: records deterministic rows until killed.

Row i has time_s = i·1 ms and every other column a known function of i, so the parent can check each
committed row exactly. After each commit it prints the number of committed rows (flushed).
"""

from __future__ import annotations

import sys
import time

from bowden.runtime.recorder import Recorder, TrialInfo


def row(i: int) -> tuple[float | int, ...]:
    t = i * 1e-3
    return (t, 0.1 * t, 0.2 * t, 0.3, 10.0 + i % 7, 0.05, 0.5 * (i % 3), 0.25, -1.0, float("nan"), 1, i % 4)


def main(path: str) -> None:
    recorder = Recorder(
        path,
        TrialInfo(participant="P01", condition="support_50", speed="V2", support=0.5,
                  metadata={"rate_hz": 1000}),
        commit_interval_s=0.05,
        on_commit=lambda n: print(f"committed {n}", flush=True),
    )
    recorder.start()
    i = 0
    next_s = time.monotonic()
    while True:  # until SIGKILL
        recorder.record(row(i))
        i += 1
        next_s += 1e-3
        delay = next_s - time.monotonic()
        if delay > 0:
            time.sleep(delay)


if __name__ == "__main__":
    main(sys.argv[1])
