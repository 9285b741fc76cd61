"""A recording that cannot be written reaches the loop and the operator: ``bowden run`` on a full disk.

The run's process gets a file-size limit (RLIMIT_FSIZE, with SIGXFSZ ignored, so a write past it
fails with EFBIG as a write to a full disk fails with ENOSPC). Measured before: rows stopped at 1.2 s
while the run went on to 15 s, then exit 1 with the trial left open and no summary. Now: a safe stop
with the recorder's reason, exit 3, the summary, and every committed row kept.
"""

from __future__ import annotations

import resource
import signal
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from bowden.store.sample_chunks import last_sample_times, sample_count

LIMIT_BYTES = 256 * 1024


def run_limited(args: list[str]) -> subprocess.CompletedProcess[str]:
    def limit_file_size() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # inherited across exec: EFBIG instead of a kill
        resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT_BYTES, LIMIT_BYTES))

    # Host stalls are not what this test is about: a loaded machine must not stop the run first.
    command = [sys.executable, "-m", "bowden", "run", "--backend", "sim", "--host-stall-ms", "2000", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=300,
                          preexec_fn=limit_file_size, check=False)


@pytest.mark.timeout(600)
def test_full_disk_stops_safely_and_keeps_what_was_written(tmp_path: Path) -> None:
    # The simulated suit's compiled kernels are cached on disk: compile them here, without the limit,
    # so that nothing but the store meets it (a first run of bowden run caches the same kernels).
    from bowden.protocol.minimum_jerk import MinimumJerkCycle
    from bowden.sim.arm import PrescribedArm
    from bowden.sim.peers.warm_up import warm_up_suit

    warm_up_suit(PrescribedArm.following(MinimumJerkCycle()))
    store = tmp_path / "study.db"
    result = run_limited(["--duration", "60", "--record", str(store), "--participant", "P03",
                          "--condition", "support_50"])
    out = result.stdout
    assert result.returncode == 3, out + result.stderr
    assert "stopped: recording failed" in out and "RECORDER_FAILED" in out, out
    # SQLite names ENOSPC "database or disk is full" and EFBIG "disk I/O error".
    assert "disk is full" in out or "disk I/O error" in out
    assert "motor mode exited" in out  # the safe-state path ran to its end
    assert "recording: recording into" in out  # the summary says what became of the recording
    with sqlite3.connect(store) as check:
        rows, last = sample_count(check), max(last_sample_times(check).values())
    assert rows > 100 and last < 50.0  # it stopped long before the 60 s, with the rows it had
