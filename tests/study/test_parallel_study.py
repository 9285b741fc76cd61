"""`bowden study` gives the same store, outcomes and statistics whatever runs it.

In this process (--workers 1), on two worker processes (--workers 2) and on a two-worker Dask cluster
on the loopback interface (--scheduler): trials are simulated in any order by any worker, written by
the parent in the protocol's order, and analysed in trial order. The single-process run is the reduced
study other files share (tests/study/reduced_study.py: 2 participants, 1 repetition, 24 trials).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pandas as pd
import pytest
from tests.study.reduced_study import N_TRIALS
from tests.study.reduced_study import SETTINGS as SMALL

from bowden.errors import ClusterError, ParameterError
from bowden.store.study_store import StudyStore
from bowden.study.pipeline import StudyResult, run_study


def _contents(result: StudyResult) -> dict[str, object]:
    model_sha256 = hashlib.sha256((result.store.parent / "model.json").read_bytes()).hexdigest()
    with StudyStore(result.store) as store:
        trials = store.read_sql("SELECT id, participant, condition, speed, metadata FROM trials ORDER BY id")
        # Each run writes its own model.json (its provenance has the time it was written), so the
        # trials name that file's hash; apart from it they must be the same.
        metadata = [json.loads(text) for text in trials["metadata"]]
        assert {meta.pop("model_sha256") for meta in metadata} == {model_sha256}
        trials["metadata"] = [json.dumps(meta, sort_keys=True) for meta in metadata]
        last = int(trials["id"].iloc[-1])
        contents: dict[str, object] = {
            "trials": trials,
            "samples": store.trial_samples(last),
            "emg": store.trial_emg(last),
            "outcomes": store.outcomes(),
            "questionnaires": store.questionnaires(),
        }
    assert result.analysis is not None
    statistics = result.analysis.statistics
    fits = [*statistics.kinematics, *(fit for phase in statistics.iemg.values() for fit in phase)]
    contents["tests"] = pd.concat([fit.tests.assign(outcome=fit.name) for fit in fits], ignore_index=True)
    contents["friedman"] = statistics.questionnaires
    contents["failures"] = pd.DataFrame({"failure": statistics.failures})
    return contents


def _assert_same(one: dict[str, object], other: dict[str, object]) -> None:
    assert one.keys() == other.keys()
    for name, frame in one.items():
        assert isinstance(frame, pd.DataFrame), name
        pd.testing.assert_frame_equal(frame, other[name], check_exact=True, obj=name)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def single_process(shared_study: StudyResult) -> dict[str, object]:
    assert shared_study.workers == 1 and shared_study.trials_simulated == N_TRIALS
    return _contents(shared_study)


def test_two_worker_processes_give_the_single_process_results(
    single_process: dict[str, object], tmp_path: Path
) -> None:
    result = run_study(SMALL, tmp_path, workers=2)
    assert result.workers == 2
    _assert_same(single_process, _contents(result))
    # CPU seconds per stage are measured beside the wall clock (the workers' included).
    assert set(result.stage_cpu_seconds) == set(result.stage_seconds)


def test_a_two_worker_dask_cluster_gives_the_single_process_results(
    single_process: dict[str, object], tmp_path: Path
) -> None:
    distributed = pytest.importorskip("distributed")
    import dask

    # Dask's profiler samples each worker's stack every 10 ms for its dashboard and performance
    # reports, which this test has neither of: about 3 s of the run's 45 s of CPU.
    with dask.config.set({"distributed.worker.profile.enabled": False}), distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        result = run_study(SMALL, tmp_path, scheduler=cluster.scheduler_address)
    assert result.workers == 2
    _assert_same(single_process, _contents(result))


def test_a_bad_scheduler_address_is_a_cluster_error_before_any_trial(tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    with pytest.raises(ClusterError, match="cannot reach the Dask scheduler at nonsense"):
        run_study(SMALL, tmp_path, scheduler="nonsense")
    assert not (tmp_path / "study.db").exists()


@pytest.mark.parametrize("workers", [0, -1, 2000, True])
def test_workers_out_of_range_are_refused(tmp_path: Path, workers: int) -> None:
    with pytest.raises(ParameterError, match="workers must be an integer in"):
        run_study(SMALL, tmp_path, workers=workers)


def test_workers_and_a_scheduler_together_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ParameterError, match="cannot be used with --scheduler"):
        run_study(SMALL, tmp_path, workers=2, scheduler="tcp://127.0.0.1:8786")
