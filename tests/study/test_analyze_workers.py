"""How many worker processes ``bowden analyze`` starts: a pool only where its start pays.

A spawned worker imports the analysis before its first trial (seconds of a core), so a store of a
handful of trials is analysed in the command's own process; ``--workers`` says otherwise.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from bowden.cli import main
from bowden.engine.pool import TASKS_PER_WORKER, pool_size
from bowden.errors import ParameterError
from bowden.store.study_store import StudyStore

CORES = os.cpu_count() or 1


def test_a_handful_of_trials_is_analysed_in_this_process() -> None:
    assert pool_size(0) == 1
    assert pool_size(TASKS_PER_WORKER - 1) == 1  # the documented real study's three, a session's five


def test_a_study_gets_one_worker_per_ten_trials_up_to_one_per_core() -> None:
    assert pool_size(2 * TASKS_PER_WORKER) == min(CORES, 2)
    assert pool_size(612) == CORES  # the paper's 17 participants x 4 conditions x 3 speeds x 3 blocks


def test_workers_given_are_taken_as_given() -> None:
    assert pool_size(1, workers=3) == 3
    assert pool_size(10_000, workers=1) == 1
    with pytest.raises(ParameterError, match="workers must be an integer"):
        pool_size(5, workers=0)


@pytest.mark.parametrize("value", ["0", "2000"])
def test_a_bad_workers_flag_is_one_line_naming_it(tmp_path: Path, value: str,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    store = tmp_path / "study.db"
    StudyStore(store).close()
    assert main(["analyze", str(store), "--workers", value, "--quiet"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"--workers must be an integer in [1, 1024], got {value}" in err[0], err
