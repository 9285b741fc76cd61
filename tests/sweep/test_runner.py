"""A small sweep on a real two-worker local Dask cluster: Parquet content, in-process parity, resuming."""

from __future__ import annotations

import json
import re
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from bowden.errors import ClusterError, OutputFileError, ParameterError
from bowden.sim.parameters import SuitParameters
from bowden.sweep import (
    RESULT_COLUMNS,
    SweepSpec,
    cohort,
    dask_client,
    identify_suit,
    protocol_settings,
    run_sweep,
    score_participant,
)
from bowden.sweep.output import RESULTS_FILE, SweepDirectory

KEY = ["point_id", "participant", "condition", "speed", "phase"]


@pytest.fixture(scope="module")
def first_run(dask_client, small_spec, tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep")
    return out, run_sweep(small_spec, out, dask_client)


def test_parquet_rows_are_complete_and_finite(first_run, small_spec):
    out, run = first_run
    results = pd.read_parquet(out / RESULTS_FILE)
    assert tuple(results.columns) == RESULT_COLUMNS
    assert len(results) == 2 * 2 * 2 * 1 * 3  # points × participants × conditions × speeds × phases
    assert not results.duplicated(KEY).any()
    scores = ["tension_rmse_n", "torque_rmse_nm", "percent_error_rmse_pct", "elevation_rmse_rad"]
    assert np.isfinite(results[scores].to_numpy()).all()
    phases = results[results["phase"] != "entire"]
    assert np.isfinite(phases[["peak_percent_error_pct", "peak_percent_error_time_pct"]].to_numpy()).all()
    assert (results["n_repetitions"] == 1).all()
    assert run.tasks_computed == 4 and run.tasks_skipped == 0 and run.models_identified == 1
    assert run.workers == 2
    points = pd.read_parquet(out / "points.parquet")
    assert len(points) == 2 and points["paper_blend"].sum() == 1
    assert set(points["blend_velocity_99_rad_s"]) == {0.5, 1.0}


def test_rows_equal_the_same_points_computed_in_process(first_run, small_spec):
    out, _ = first_run
    results = pd.read_parquet(out / RESULTS_FILE)
    model = identify_suit(SuitParameters(), small_spec.bench, 0)
    saved = SweepDirectory(out).load_model(next((out / "models").glob("*.json")).stem)
    assert saved is not None and saved.raising == model.raising and saved.lowering == model.lowering
    frames = [
        score_participant(point, SuitParameters(), model, participant, index, protocol_settings(small_spec))
        for point in small_spec.points()
        for index, participant in enumerate(cohort(small_spec, point.seed))
    ]
    local = pd.concat(frames, ignore_index=True)
    pd.testing.assert_frame_equal(
        results.sort_values(KEY).reset_index(drop=True), local.sort_values(KEY).reset_index(drop=True)
    )


def test_a_second_run_resumes_and_recomputes_only_what_is_missing(first_run, small_spec, dask_client):
    out, run = first_run
    again = run_sweep(small_spec, out, dask_client)
    assert again.tasks_computed == 0 and again.tasks_skipped == 4 and again.models_identified == 0
    pd.testing.assert_frame_equal(again.results, run.results)
    # A lost part (a task that never finished) and a lost model: only those are computed again.
    point = small_spec.points()[1]
    participant = cohort(small_spec, 0)[0].participant_id
    SweepDirectory(out).part_path(point.point_id, participant).unlink()
    for model in (out / "models").glob("*.json"):
        model.unlink()
    resumed = run_sweep(small_spec, out, dask_client)
    assert resumed.tasks_computed == 1 and resumed.tasks_skipped == 3 and resumed.models_identified == 1
    pd.testing.assert_frame_equal(resumed.results, run.results)
    assert not list(out.rglob("*.tmp"))  # atomic writes leave nothing behind


def test_a_damaged_part_is_computed_again(first_run, small_spec, dask_client, tmp_path):
    out, run = first_run
    point = small_spec.points()[0]
    participant = cohort(small_spec, 0)[1].participant_id
    SweepDirectory(out).part_path(point.point_id, participant).write_bytes(b"PAR1 not a parquet file")
    resumed = run_sweep(small_spec, out, dask_client)
    assert resumed.tasks_computed == 1 and resumed.tasks_skipped == 3
    pd.testing.assert_frame_equal(resumed.results, run.results)


def test_an_output_path_that_is_a_file_is_refused(small_spec, dask_client, tmp_path):
    taken = tmp_path / "results.csv"
    taken.write_text("someone's data\n")
    with pytest.raises(OutputFileError, match="is a file"):
        run_sweep(small_spec, taken, dask_client)
    assert taken.read_text() == "someone's data\n"


def test_another_spec_or_simulator_is_not_mixed_in(first_run, small_spec, dask_client, tmp_path):
    out, _ = first_run
    other = replace(small_spec, participants=3)
    with pytest.raises(ParameterError, match="holds a sweep with another spec"):
        run_sweep(other, out, dask_client)
    # Results of another simulator: the recorded digest differs.
    copy = tmp_path / "copy"
    copy.mkdir()
    record = json.loads((out / "spec.json").read_text())
    record["simulator_sha256"] = "0" * 16
    (copy / "spec.json").write_text(json.dumps(record))
    with pytest.raises(ParameterError, match="another version of the simulator"):
        run_sweep(small_spec, copy, dask_client)
    # A directory that holds something else is refused too.
    stranger = tmp_path / "stranger"
    stranger.mkdir()
    (stranger / "notes.txt").write_text("mine")
    with pytest.raises(ParameterError, match="holds no sweep"):
        run_sweep(small_spec, stranger, dask_client)


def test_force_starts_again(small_spec, dask_client, tmp_path):
    one_point = SweepSpec(
        name="force",
        axes=(("blend_velocity_99_rad_s", (0.5,)),),
        participants=2,
        repetitions=2,
        conditions=("support_50",),
        speeds=("V3",),
        bench="quick",
    )
    run_sweep(one_point, tmp_path, dask_client)
    (tmp_path / "models" / "stale.json").write_text("{}")
    forced = run_sweep(one_point, tmp_path, dask_client, force=True)
    assert forced.tasks_computed == 2 and not (tmp_path / "models" / "stale.json").exists()


def test_unreachable_scheduler_is_a_cluster_error():
    expected = re.escape("cannot reach the Dask scheduler at tcp://127.0.0.1:9")
    with pytest.raises(ClusterError, match=expected), dask_client("tcp://127.0.0.1:9", connect_timeout_s=1.0):
        pass


def test_workers_with_a_scheduler_is_refused():
    with pytest.raises(ParameterError, match="--workers"), dask_client("tcp://127.0.0.1:9", 2):
        pass


def test_a_worker_that_dies_mid_run_loses_nothing(first_run, small_spec, dask_client, tmp_path):
    # Kill one worker process (its nanny starts a new one) as soon as the first task is on disk: the
    # scheduler runs its work elsewhere, and the run ends with exactly the rows of an undisturbed run.
    import contextlib
    import os
    import threading
    import time

    outcome: dict[str, object] = {}

    def sweep() -> None:
        try:
            outcome["run"] = run_sweep(small_spec, tmp_path, dask_client)
        except BaseException as exc:  # handed to the test thread
            outcome["error"] = exc

    worker = threading.Thread(target=sweep)
    worker.start()
    deadline = time.monotonic() + 60.0
    while not list((tmp_path / "parts").rglob("*.parquet")) and worker.is_alive():
        assert time.monotonic() < deadline, "no task finished within 60 s"
        time.sleep(0.01)
    victim = sorted(dask_client.scheduler_info()["workers"])[0]
    killed_mid_run = worker.is_alive()
    with contextlib.suppress(Exception):  # the worker dies before it can answer
        dask_client.run(os._exit, 1, workers=[victim])
    worker.join(timeout=120.0)
    assert not worker.is_alive()
    assert killed_mid_run  # tasks last ≥ 0.1 s: the kill came before the last one finished
    assert "error" not in outcome, outcome.get("error")
    pd.testing.assert_frame_equal(outcome["run"].results, first_run[1].results)  # type: ignore[union-attr]
    dask_client.wait_for_workers(2, timeout=60.0)  # the nanny's new worker, for whoever comes next
