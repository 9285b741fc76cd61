"""The bench recording written stroke by stroke: what a crash leaves, what a resume does, and that
``bowden identify``'s reader takes the file as it is."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from bowden.errors import OutputFileError, RecordingError
from bowden.identify.recording import read_bench_recording
from bowden.runtime.bench_recording import LOG_COLUMNS, RECORDING_COLUMNS, BenchRecordingWriter

PROTOCOL = {"spool_speeds_rad_s": [1.0], "loads_nm": [1.0], "repetitions": 1}


def stroke(trial: int, start_s: float, n: int = 50) -> tuple[np.ndarray, np.ndarray]:
    t = start_s + np.arange(n) * 0.005
    elevation = np.linspace(0.35, 1.9, n) if trial % 2 == 0 else np.linspace(1.9, 0.35, n)
    tension = 20.0 + 10.0 * np.sin(t)
    rows = np.column_stack([t, 0.1 + 0.04 * tension, np.full(n, 2.0), tension, elevation, np.full(n, trial)])
    log = np.column_stack([t, np.full(n, trial), np.ones(n), *(np.zeros((7, n)))])
    return rows, log


def test_strokes_are_on_disk_as_they_complete_and_identify_reads_them(tmp_path):
    path = tmp_path / "bench.csv"
    with BenchRecordingWriter(path, PROTOCOL) as writer:
        for k in range(2):
            writer.write_stroke(*stroke(k, k * 0.3), strokes_done=k + 1)
        journal = json.loads(writer.journal_path.read_text())
        assert journal["strokes_done"] == 2 and journal["data_bytes"] == path.stat().st_size
        writer.finish()
    frame = pd.read_csv(path)
    assert tuple(frame.columns) == RECORDING_COLUMNS
    assert list(frame["trial"].unique()) == [0, 1]
    assert tuple(pd.read_csv(tmp_path / "bench.log.csv").columns) == LOG_COLUMNS
    recording = read_bench_recording([path])
    assert recording.n_samples == 100


def test_a_crash_mid_write_is_cut_back_to_the_last_complete_stroke_on_resume(tmp_path):
    path = tmp_path / "bench.csv"
    writer = BenchRecordingWriter(path, PROTOCOL)
    writer.write_stroke(*stroke(0, 0.0), strokes_done=1)
    writer.close()
    with path.open("a") as handle:  # what a crash in the middle of the next stroke leaves
        handle.write("0.31,0.9,2.0,21.0,0.4,1\n0.315,0.9,")
    with pytest.raises(OutputFileError, match="--resume"):
        BenchRecordingWriter(path, PROTOCOL)
    resumed = BenchRecordingWriter(path, PROTOCOL, resume=True)
    assert resumed.resume_point.strokes_done == 1
    assert resumed.resume_point.last_time_s == pytest.approx(49 * 0.005)
    resumed.write_stroke(*stroke(1, 1.0), strokes_done=2)
    resumed.finish()
    frame = pd.read_csv(path)
    assert len(frame) == 100 and frame["time_s"].is_monotonic_increasing
    with pytest.raises(OutputFileError, match="already complete"):
        BenchRecordingWriter(path, PROTOCOL, resume=True)


def test_refusals_name_the_problem(tmp_path):
    path = tmp_path / "bench.csv"
    path.write_text("someone else's file\n")
    with pytest.raises(OutputFileError, match="no journal"):
        BenchRecordingWriter(path, PROTOCOL)
    with pytest.raises(OutputFileError, match="format"):
        BenchRecordingWriter(tmp_path / "bench.txt", PROTOCOL)
    with pytest.raises(OutputFileError, match="nothing to resume"):
        BenchRecordingWriter(tmp_path / "new.csv", PROTOCOL, resume=True)
    # A missing folder is said to be missing (it was "is not a directory"), a file as a folder is not one.
    with pytest.raises(OutputFileError, match=r"the folder .*nodir does not exist"):
        BenchRecordingWriter(tmp_path / "nodir" / "x.csv", PROTOCOL)
    with pytest.raises(OutputFileError, match=r"the folder .*bench\.csv is not a directory"):
        BenchRecordingWriter(path / "x.csv", PROTOCOL)
    writer = BenchRecordingWriter(tmp_path / "a.csv", PROTOCOL)
    writer.write_stroke(*stroke(0, 0.0), strokes_done=1)
    writer.close()
    with pytest.raises(OutputFileError, match="another protocol"):
        BenchRecordingWriter(tmp_path / "a.csv", {**PROTOCOL, "repetitions": 5}, resume=True)
    (tmp_path / "a.csv").write_text("time_s\n")  # shortened behind the journal's back
    with pytest.raises(RecordingError, match="shorter than its journal"):
        BenchRecordingWriter(tmp_path / "a.csv", PROTOCOL, resume=True)


def test_parquet_is_written_once_the_protocol_is_complete(tmp_path):
    pytest.importorskip("pyarrow")
    path = tmp_path / "bench.parquet"
    with BenchRecordingWriter(path, PROTOCOL) as writer:
        writer.write_stroke(*stroke(0, 0.0), strokes_done=1)
        assert not path.exists() and writer.data_path.exists()
        writer.finish()
    assert not writer.data_path.exists()
    assert len(pd.read_parquet(path)) == 50


def test_a_resume_continues_after_the_device_log_of_the_stroke_under_way(tmp_path):
    # Issue 26, item 9: the log of the stroke under way at a stop reaches past the last recorded
    # stroke; a resume's times start after it, so the device log stays in time order.
    path = tmp_path / "bench.csv"
    with BenchRecordingWriter(path, PROTOCOL) as writer:
        learned = {"points": [[[0.35, 1.0, -1.0, 0.35, 0.4]]]}
        writer.write_stroke(*stroke(0, 0.0), strokes_done=1, learned=learned)
        _, partial = stroke(1, 5.0)
        writer.write_log(partial)  # positioning, hold and half a stroke, until 5.245 s
    with BenchRecordingWriter(path, PROTOCOL, resume=True) as writer:
        assert writer.resume_point.strokes_done == 1
        assert writer.resume_point.last_time_s == pytest.approx(5.245)
        assert writer.resume_point.learned == learned


def test_a_recording_without_a_stroke_does_not_block_the_next_start(tmp_path):
    # Issue 26, item 4: a run that stopped before its first stroke (a load the bench cannot hold)
    # leaves a journal of 0 strokes; the next run starts without --resume, with its own protocol,
    # and keeps the earlier device log.
    path = tmp_path / "bench.csv"
    with BenchRecordingWriter(path, {**PROTOCOL, "loads_nm": [12.0]}) as writer:
        _, log = stroke(0, 0.0)
        writer.write_log(log)
    with BenchRecordingWriter(path, PROTOCOL) as writer:
        assert writer.resume_point.strokes_done == 0
        assert writer.resume_point.last_time_s == pytest.approx(0.245)
        writer.write_stroke(*stroke(0, 1.245), strokes_done=1)
    assert json.loads((tmp_path / "bench.csv.journal").read_text())["protocol"] == PROTOCOL
    assert len(pd.read_csv(tmp_path / "bench.log.csv")) == 100
    assert pd.read_csv(tmp_path / "bench.log.csv")["time_s"].is_monotonic_increasing


def test_a_crash_in_a_later_segment_resumes_into_it_with_its_complete_blocks(tmp_path):
    from bowden.runtime.bench_recording import STUDY_COLUMNS

    path = tmp_path / "bench.csv"
    writer = BenchRecordingWriter(path, PROTOCOL)
    writer.write_stroke(*stroke(0, 0.0), strokes_done=1)
    chirp = np.column_stack([1.0 + np.arange(20) * 0.005, np.full(20, 1.0), np.full(20, 1.01)])
    writer.write_segment("latency", chirp, np.empty((0, len(LOG_COLUMNS))), units_done=2)
    block = np.zeros((10, len(STUDY_COLUMNS)))
    block[:, 0] = 2.0 + np.arange(10) * 0.005
    writer.write_segment("study", block, np.empty((0, len(LOG_COLUMNS))), units_done=3)
    writer.close()
    study = tmp_path / "bench.study.csv"
    with study.open("a") as handle:  # the second block under way when the run crashed
        handle.write("3.0,1,0.5,3,1,0.1,0.2")
    resumed = BenchRecordingWriter(path, PROTOCOL, resume=True)
    assert resumed.resume_point.strokes_done == 3  # the next unit: the second study-like block
    assert resumed.resume_point.last_time_s == pytest.approx(2.045)
    later = block.copy()
    later[:, 0] += 1.0
    resumed.write_segment("study", later,
                          np.empty((0, len(LOG_COLUMNS))), units_done=4)
    resumed.finish()
    frame = pd.read_csv(study)
    assert tuple(frame.columns) == STUDY_COLUMNS and len(frame) == 20  # the partial line is gone
    assert len(pd.read_csv(tmp_path / "bench.latency.csv")) == 20
    assert pd.read_csv(path)["trial"].nunique() == 1  # the strokes' recording holds only strokes


def test_a_study_file_with_other_columns_is_not_resumed_into(tmp_path):
    # A run started before the study-like segment had its fit and candidate columns: appending rows of
    # sixteen columns under a header of fourteen would be misread, so the resume is refused.
    from bowden.runtime.bench_recording import STUDY_COLUMNS

    path = tmp_path / "bench.csv"
    writer = BenchRecordingWriter(path, PROTOCOL)
    block = np.zeros((10, len(STUDY_COLUMNS)))
    block[:, 0] = 1.0 + np.arange(10) * 0.005
    writer.write_segment("study", block, np.empty((0, len(LOG_COLUMNS))), units_done=1)
    writer.close()
    study = tmp_path / "bench.study.csv"
    text = study.read_text().replace(",fit,candidate\n", "\n", 1).replace(",0,0\n", "\n")
    study.write_text(text)
    journal = json.loads((tmp_path / "bench.csv.journal").read_text())
    journal["segments"]["study"] = len(text.encode())
    (tmp_path / "bench.csv.journal").write_text(json.dumps(journal))
    with pytest.raises(RecordingError, match="other columns than this bowden writes"):
        BenchRecordingWriter(path, PROTOCOL, resume=True)


def test_a_validation_is_not_resumed_with_another_model(tmp_path):
    # bench validate's blocks ran one model's coefficients: a resume with another model's would mix
    # the two in one recording, so it is refused; a model whose per-cell recommendation alone was
    # rewritten (bench validate -o MODEL) runs the same blocks and resumes.
    from dataclasses import replace

    from bowden.model import CompensationModel
    from bowden.model.model_record import controller_sha256
    from bowden.runtime.bench_config import BenchRunConfig

    model = CompensationModel.from_friction(k=0.1)
    other = CompensationModel.from_friction(k=0.12)
    assert controller_sha256(model) != controller_sha256(other)
    started = BenchRunConfig(identification=False, model_digest=controller_sha256(model))
    assert BenchRunConfig(identification=False).protocol_fingerprint().get("model") is None  # bench run
    path = tmp_path / "validate.csv"
    writer = BenchRecordingWriter(path, started.protocol_fingerprint())
    writer.write_stroke(*stroke(0, 0.0), strokes_done=1)
    writer.close()
    resumed = replace(started, model_digest=controller_sha256(other))
    with pytest.raises(OutputFileError, match="with another model"):
        BenchRecordingWriter(path, resumed.protocol_fingerprint(), resume=True)
    BenchRecordingWriter(path, started.protocol_fingerprint(), resume=True).close()


def test_the_controller_digest_leaves_out_the_recommendation_only():
    from dataclasses import replace

    from bowden.identify import TransmissionIdentifier
    from bowden.model.model_record import controller_sha256
    from bowden.protocol.bench import QUICK_BENCH
    from bowden.sim.bench import run_bench
    from bowden.sim.parameters import SuitParameters

    model = TransmissionIdentifier().fit(run_bench(SuitParameters(), QUICK_BENCH, seed=0)).model_
    assert model.dynamic is not None
    told = replace(model, dynamic=replace(model.dynamic, recommended=not model.dynamic.recommended,
                                          recommendation="another line"))
    assert controller_sha256(told) == controller_sha256(model)
    heavier = replace(model, dynamic=replace(model.dynamic, inertia_kg_m2=model.dynamic.inertia_kg_m2 * 2))
    assert controller_sha256(heavier) != controller_sha256(model)
