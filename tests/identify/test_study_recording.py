"""The recorded study-like segment judged per cell (identify/study_recording.py) against hand values,
and the protocol's later segments holding the batch segments' numbers (the chirp: one definition)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from bowden.errors import FitError, ParameterError
from bowden.identify.study_recording import judge_block, read_study_recording
from bowden.protocol.bench import LatencyChirp, StudyStrokes
from bowden.runtime.bench_recording import STUDY_COLUMNS


def _block(error_n: float, onset_extra_n: float, *, repetitions: int = 3, n: int = 1000) -> pd.DataFrame:
    """A block whose tension is the law + ``error_n``, + ``onset_extra_n`` more at 60 % of each cycle."""
    phase = np.concatenate([np.linspace(-0.5, 0.0, 50, endpoint=False),
                            np.linspace(0.0, repetitions, repetitions * n, endpoint=False)])
    law = np.full(phase.size, 20.0)
    in_cycle = np.concatenate([np.full(50, -1), np.arange(repetitions * n) % n])
    # 51 samples about 60 % of the cycle: whole 1 % bins from 58 % to 61 % (whatever rounding does
    # at a bin's edge).
    onset = (in_cycle >= 575) & (in_cycle <= 625)
    tension = law + error_n + np.where(onset, onset_extra_n, 0.0)
    frame = pd.DataFrame(0.0, index=np.arange(phase.size), columns=list(STUDY_COLUMNS))
    frame["cycle_phase"], frame["law_tension_n"], frame["tension_n"] = phase, law, tension
    return frame


def test_a_block_is_judged_on_its_repetitions_after_the_first():
    frame = _block(2.0, 4.0)
    result = judge_block(frame["cycle_phase"].to_numpy(), frame["tension_n"].to_numpy(),
                         frame["law_tension_n"].to_numpy())
    # 51 of each 1000 samples per cycle carry 6 N, the rest 2 N.
    assert result.tension_rmse_n == pytest.approx(math.sqrt((949 * 4.0 + 51 * 36.0) / 1000), rel=1e-9)
    assert result.onset_peak_pct == pytest.approx(30.0)  # (2 + 4) / 20 in the bins about 60 %
    # The first repetition does not count: an error there changes nothing.
    first = frame.copy()
    first.loc[(first["cycle_phase"] >= 0) & (first["cycle_phase"] < 1), "tension_n"] += 50.0
    again = judge_block(first["cycle_phase"].to_numpy(), first["tension_n"].to_numpy(),
                        first["law_tension_n"].to_numpy())
    assert again.tension_rmse_n == result.tension_rmse_n


def test_the_file_is_read_per_cell_and_compensation(tmp_path):
    paper, dynamic = _block(4.0, 0.0), _block(1.0, 0.0)
    for block, (frame, name) in enumerate(((paper, 0), (dynamic, 1))):
        frame["block"], frame["support"], frame["speed"], frame["compensation"] = block, 0.25, 2, name
    path = tmp_path / "bench.study.csv"
    pd.concat([paper, dynamic]).to_csv(path, index=False)
    results = read_study_recording(path)
    assert list(results) == [("25", "V2")]
    assert results[("25", "V2")]["paper"].tension_rmse_n == pytest.approx(4.0)
    assert results[("25", "V2")]["dynamic"].onset_peak_pct == pytest.approx(5.0)
    pd.concat([paper, dynamic]).drop(columns="law_tension_n").to_csv(path, index=False)
    with pytest.raises(FitError, match=r"--study-recording .*law_tension_n"):
        read_study_recording(path)


def test_the_bench_runs_the_batch_segments_numbers():
    from bowden.identify.study_fit import STUDY_SUPPORTS
    from bowden.identify.study_recommendation import VALIDATION_REPETITIONS
    from bowden.sim import bench_study

    study = StudyStrokes()
    assert study.stiffness_nm_rad == bench_study.MANNEQUIN_STIFFNESS_NM_RAD
    assert study.damping_nms_rad == bench_study.MANNEQUIN_DAMPING_NMS_RAD
    assert (study.motor_noise_nm, study.motor_noise_fraction, study.motor_noise_time_s) == (
        bench_study.MANNEQUIN_MOTOR_NOISE_NM, bench_study.MANNEQUIN_MOTOR_NOISE_FRACTION,
        bench_study.MANNEQUIN_MOTOR_NOISE_TIME_S)
    assert study.supports == STUDY_SUPPORTS
    assert study.repetitions == VALIDATION_REPETITIONS


def test_the_batch_bench_moves_the_arm_along_the_protocols_chirp():
    # One chirp for both benches: the batch bench prescribes LatencyChirp.elevation to the arm and logs
    # the encoder at the protocol's 200 Hz.
    from bowden.sim.bench_latency import ENCODER_ELEVATION, TIME, run_latency_segment

    chirp = LatencyChirp(duration_s=3.0, start_hz=0.5, end_hz=1.5)
    segment = run_latency_segment(chirp=chirp, seed=1)
    times = segment[TIME].to_numpy()
    assert np.allclose(np.diff(times), 0.005) and times[-1] == pytest.approx(3.0)
    theta, _ = chirp.elevation(times)
    assert np.allclose(segment[ENCODER_ELEVATION].to_numpy(), theta, atol=1e-9)
    assert len(run_latency_segment(chirp=chirp, sample_rate_hz=100.0)) == len(times) // 2
    with pytest.raises(ParameterError, match="the latency segment's sample rate"):
        run_latency_segment(chirp=chirp, sample_rate_hz=0.0)


def _fit_recording(path, candidates: dict[int, float], *, validation: bool = True, drop: int | None = None):
    """A recorded study-like fit at 50 % V2: the paper's block (error 4 N, onset +6 N), one block per
    candidate with the given constant error (N, no onset excess), then a validation pair."""
    frames = [(_block(4.0, 6.0), 0, 1, -1)]
    frames += [(_block(error, 0.0), 1, 1, candidate) for candidate, error in candidates.items()]
    if validation:
        frames += [(_block(4.0, 0.0), 0, 0, -1), (_block(2.0, 0.0), 1, 0, -1)]
    blocks = []
    for number, (frame, compensation, fit, candidate) in enumerate(frames):
        if number == drop:
            continue
        frame["block"], frame["support"], frame["speed"] = number, 0.5, 2
        frame["compensation"], frame["fit"], frame["candidate"] = compensation, fit, candidate
        blocks.append(frame)
    pd.concat(blocks).to_csv(path, index=False)


def test_a_recorded_fit_chooses_the_candidate_of_lowest_study_cost(tmp_path):
    from bowden.identify.study_fit import fit_candidate
    from bowden.identify.study_recording import choose_fitted
    from bowden.model import CompensationModel

    path = tmp_path / "v.study.csv"
    _fit_recording(path, {3: 2.0, 5: 1.0, 8: 3.0})
    model = _dynamic_model()
    choice = choose_fitted(model, path, "--recording")
    # By hand: the paper's RMSE sqrt((949·16 + 51·100) / 1000), its onset peak (4 + 6) / 20 = 50 %; a
    # candidate's cost is its error over that RMSE plus its onset peak (error / 20 N) over 50 %.
    paper_rmse = math.sqrt((949 * 16.0 + 51 * 100.0) / 1000)
    expected = {k: e / paper_rmse + (100 * e / 20) / 50.0 for k, e in {3: 2.0, 5: 1.0, 8: 3.0}.items()}
    assert choice.costs == pytest.approx(expected, rel=1e-9)
    assert choice.candidate == 5 and choice.model == fit_candidate(model, 5)
    assert isinstance(choice.model, CompensationModel)
    # The held-out validation blocks are judged apart from the fit's.
    results = read_study_recording(path, after_fit=True)
    assert results[("50", "V2")]["dynamic"].tension_rmse_n == pytest.approx(2.0)


def test_a_recording_without_a_whole_fit_is_refused_in_one_line(tmp_path):
    from bowden.identify.study_recording import choose_fitted

    path = tmp_path / "v.study.csv"
    model = _dynamic_model()
    _fit_recording(path, {}, validation=True)  # no candidate blocks: a plain study-like segment
    with pytest.raises(FitError, match=r"--recording .*holds no candidate blocks .*fit and candidate"):
        choose_fitted(model, path, "--recording")
    old = tmp_path / "old.study.csv"  # written before the columns existed: no fit in it either
    pd.read_csv(path).drop(columns=["fit", "candidate"]).to_csv(old, index=False)
    assert list(read_study_recording(old)) == [("50", "V2")]
    with pytest.raises(FitError, match="holds no candidate blocks"):
        choose_fitted(model, old, "--recording")
    _fit_recording(path, {0: 1.0, 1: 2.0}, drop=0)  # the fit's paper block lost: incomplete
    with pytest.raises(FitError, match="the study-like fit is incomplete: candidate 0"):
        choose_fitted(model, path, "--recording")
    _fit_recording(path, {0: 1.0, 1: 2.0})  # a fit judged as a plain segment would mix candidates
    with pytest.raises(FitError, match="--fit"):
        read_study_recording(path)
    _fit_recording(path, {0: 1.0, 1: 2.0}, validation=False)  # stopped before the validation
    with pytest.raises(FitError, match="no study-like blocks after the fit"):
        read_study_recording(path, after_fit=True)


def test_bench_validate_recording_fit_says_what_is_missing(tmp_path, capsys):
    from bowden.cli import main
    from bowden.model.model_file import save_model

    model, path = tmp_path / "model.json", tmp_path / "v.study.csv"
    save_model(_dynamic_model(), model)
    _fit_recording(path, {})
    assert main(["bench", "validate", str(model), "--recording", str(path), "--fit"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--recording" in err[0] and "candidate blocks" in err[0], err
    _fit_recording(path, {2: 1.0, 4: 0.5})
    assert main(["bench", "validate", str(model), "--recording", str(path), "--fit"]) == 0
    assert "fitted: candidate 4 (drag ×1.4, inertia ×1, lowering line +0 Nm)" in capsys.readouterr().out


def _dynamic_model():
    from bowden.identify import TransmissionIdentifier
    from bowden.protocol.bench import QUICK_BENCH
    from bowden.sim.bench import run_bench
    from bowden.sim.parameters import SuitParameters

    model = TransmissionIdentifier().fit(run_bench(SuitParameters(), QUICK_BENCH, seed=0)).model_
    assert model.dynamic is not None
    return model


def test_identify_refuses_a_recorded_fit_before_it_fits_the_lines(tmp_path, capsys):
    # The study-like recording is judged before the bench recording is read and fitted: the file it
    # refuses costs no fit (and here the bench file, unreadable, would have been the error instead).
    from bowden.cli import main

    study, bench = tmp_path / "v.study.csv", tmp_path / "bench.csv"
    _fit_recording(study, {0: 1.0, 1: 2.0})
    bench.write_text("not a bench recording\n", encoding="utf-8")
    code = main(["identify", str(bench), "-o", str(tmp_path / "m.json"), "--study-recording", str(study)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0 and len(err) == 1, err
    assert "--study-recording" in err[0] and "bench validate MODEL" in err[0], err
    assert not (tmp_path / "m.json").exists()


def test_a_block_covers_its_cycles_when_the_judge_keeps_its_last_repetition():
    # The bench runs a block again when its rows stop short of its last cycle (a host stall there),
    # by the judge's own rule: a last repetition recorded below 95 % of its cycle is left out.
    from bowden.identify.study_recording import covers_its_cycles

    whole = np.arange(0.0, 2.0, 0.002)  # two cycles, rows up to 1.998
    assert covers_its_cycles(whole, 2)
    short = whole[whole < 1.94]  # the last 6 % of the second cycle missing
    assert not covers_its_cycles(short, 2) and not covers_its_cycles(np.array([]), 2)
    law = np.full(short.size, 20.0)
    with pytest.raises(FitError, match="no repetition after the first"):  # what the bench now avoids
        judge_block(short, law + 1.0, law)
    assert judge_block(whole, np.full(whole.size, 21.0), np.full(whole.size, 20.0)).tension_rmse_n == 1.0
    assert covers_its_cycles(np.arange(0.0, 3.0, 0.002)[:-20], 3)  # 4 % of a cycle short of 3: kept
