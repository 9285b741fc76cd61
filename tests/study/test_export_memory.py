"""The export streams: four times the data costs no more memory (peak RSS of a child process)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bowden.contracts import MUSCLES, TRIAL_COLUMNS
from bowden.runtime.recorder import TrialInfo
from bowden.store.study_store import StudyStore

ROWS = 32768  # two chunks' worth of samples per trial (65 s at 500 Hz)
EMG_SAMPLES = 40000  # 20 s at 2 kHz

# Export in a fresh interpreter and print its peak resident memory (kB on Linux).
CHILD = """
import resource, sys
from bowden.store.study_store import StudyStore
with StudyStore(sys.argv[1]) as store:
    store.export(sys.argv[2], file_format=sys.argv[3], include_emg=True)
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def make_store(path: Path, trials: int) -> Path:
    rng = np.random.default_rng(trials)
    with StudyStore(path) as store:
        for i in range(trials):
            samples = pd.DataFrame({name: rng.normal(size=ROWS) for name in TRIAL_COLUMNS})
            samples["time_s"] = np.arange(ROWS) * 0.002
            samples["controller_state"], samples["fault_flags"] = 1, 0
            emg = pd.DataFrame({"time_s": np.arange(EMG_SAMPLES) / 2000.0,
                                **{m: rng.normal(0, 1e-4, EMG_SAMPLES) for m in MUSCLES}})
            info = TrialInfo(participant=f"P{i:02d}", condition="support_50", speed="V2", support=0.5)
            store.write_trial(info, samples, emg=emg)
    return path


def peak_mb(store: Path, out: Path, file_format: str) -> float:
    result = subprocess.run([sys.executable, "-c", CHILD, str(store), str(out), file_format],
                            capture_output=True, text=True, check=True)
    return int(result.stdout.strip()) / 1024


@pytest.fixture(scope="module")
def stores(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The stores of 4 and of 16 trials, made once: each format exports them (an export only reads)."""
    directory = tmp_path_factory.mktemp("export_memory")
    return make_store(directory / "small.db", 4), make_store(directory / "large.db", 16)


@pytest.mark.parametrize("file_format", ["parquet", "csv"])
def test_four_times_the_data_does_not_raise_the_peak(
    stores: tuple[Path, Path], tmp_path: Path, file_format: str
) -> None:
    small, large = stores
    # 12 more trials: 37 MB more samples and 31 MB more EMG once decoded (and twice that as labelled
    # rows), which an export holding a whole table would add to its peak.
    small_peak = peak_mb(small, tmp_path / "small", file_format)
    large_peak = peak_mb(large, tmp_path / "large", file_format)
    assert large_peak - small_peak < 25.0, (small_peak, large_peak)
    exported = pd.read_parquet(tmp_path / "large" / "samples.parquet") if file_format == "parquet" else None
    if exported is not None:
        assert len(exported) == 16 * ROWS
