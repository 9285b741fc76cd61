"""A bench recording that cannot be written is a safe stop that keeps whole strokes.

``bowden bench run`` runs with a file-size limit (RLIMIT_FSIZE, SIGXFSZ ignored: a write past it fails
with EFBIG as a full disk fails with ENOSPC). The bench stops safely (exit 3) naming the recording,
and the file holds the strokes completed before, whole, so that ``bowden identify`` reads it as it is.
"""

from __future__ import annotations

import resource
import signal
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from bowden.identify.recording import read_bench_recording

# A stroke (1 rad/s over 20°–50°: no scouting move before it) writes about 18 KB of recording and 31 KB
# of device log (measured); 12 need about 600 KB, so the limit falls after a few strokes (three, idle),
# never in the first (it is longer under load).
LIMIT_BYTES = 96 * 1024


@pytest.mark.timeout(600)
def test_a_full_disk_stops_the_bench_and_keeps_whole_strokes(tmp_path: Path) -> None:
    def limit_file_size() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT_BYTES, LIMIT_BYTES))

    # The plant's compiled kernels are cached on disk: compile them here, without the limit, so that
    # nothing but the recording meets it in the bench's processes.
    from bowden.sim.arm import MannequinArm
    from bowden.sim.peers.warm_up import warm_up_suit

    warm_up_suit(MannequinArm(load_torque_nm=1.0))
    output = tmp_path / "bench.csv"
    command = [sys.executable, "-m", "bowden", "bench", "run", "--backend", "sim", "-o", str(output),
               "--speeds", "1", "--loads", "1", "--repetitions", "6", "--high-deg", "50"]
    result = subprocess.run(command, capture_output=True, text=True, timeout=500,
                            preexec_fn=limit_file_size, check=False)
    assert result.returncode == 3, result.stdout + result.stderr
    assert "bench stopped safely: recording failed" in result.stderr, result.stderr
    frame = pd.read_csv(output)
    strokes = frame["trial"].nunique()
    assert 1 <= strokes < 12
    assert f"{strokes} of 12 strokes are recorded" in result.stderr
    assert read_bench_recording([output]).n_samples == len(frame)  # whole strokes: identify reads it
