"""``bowden bench validate MODEL --backend sim-wire --fit``: the study-like fit on the simulated bench
over its wire peers (docs/identification.md, "The protocol, exactly": the fit's blocks). Shortened
through the run's one internal knob (``default_fit``: 2 candidates, V3, 2 cycles; the command's own
default is the whole grid): it records each block's candidate, is interrupted within the fit and
resumes without running a finished block again, chooses the candidate whose study cost — computed here
from the recording alone — is lowest, and validates that candidate on blocks after the fit. A
study-like block recorded while the load cell's reader was starved is run again (its stale tension
would judge a candidate)."""

from __future__ import annotations

import json
import math
import time
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

import bowden.cli._bench_run as bench_run
import bowden.cli._bench_validate as bench_validate
from bowden.cli import main
from bowden.errors import ParameterError
from bowden.identify import TransmissionIdentifier
from bowden.identify.study_fit import FIT_REPETITIONS, fit_candidate, fit_grid
from bowden.model import CompensationModel
from bowden.model.model_file import load_model, save_model
from bowden.protocol.bench import QUICK_BENCH, StudyFit, StudyStrokes
from bowden.runtime.bench import BenchDevices, BenchRun, BenchRunConfig
from bowden.runtime.bench_recording import STUDY_COLUMNS, BenchRecordingWriter
from bowden.sim.backend import open_sim_bench
from bowden.sim.bench import run_bench
from bowden.sim.parameters import SuitParameters

CANDIDATES = (0, 11)  # the grid's first (the model as identified) and last (drag ×1.8, inertia ×2, −0.05 Nm)


def _cost_terms(rows: pd.DataFrame) -> tuple[float, float]:
    """RMSE (N) and lowering-onset peak (%) of a block's held-out cycle (cycle_phase in [1, 2)), written
    out here from the recording's columns rather than taken from the reader under test."""
    held = rows[(rows["cycle_phase"] >= 1.0) & (rows["cycle_phase"] < 2.0)]
    error = (held["tension_n"] - held["law_tension_n"]).to_numpy()
    percent = 100.0 * error / held["law_tension_n"].to_numpy()
    bins = np.minimum(((held["cycle_phase"].to_numpy() % 1.0) * 100).astype(int), 99)
    curve = pd.Series(percent).groupby(bins).mean()  # the mean percent error in each 1 % bin
    onset = curve[[b for b in curve.index if 0.45 <= (b + 0.5) / 100 <= 0.75]]
    return float(np.sqrt(np.mean(error**2))), float(onset.max())


def test_the_fit_runs_on_the_wire_bench_resumes_and_validates_its_choice(tmp_path, monkeypatch, capsys):
    model_path, fitted_path = tmp_path / "model.json", tmp_path / "fitted.json"
    model = TransmissionIdentifier().fit(run_bench(SuitParameters(), QUICK_BENCH, seed=0)).model_
    assert model.dynamic is not None
    save_model(model, model_path)
    monkeypatch.setattr(bench_validate, "default_fit", lambda args: StudyFit(
        grid=fit_grid(), candidates=CANDIDATES, support=args.support, speeds=("V3",), repetitions=2))
    command = ["bench", "validate", str(model_path), "--backend", "sim-wire", "--fit", "--support", "0.5",
               "--study-speeds", "V3", "--study-repetitions", "2", "--bench-output", str(tmp_path / "v.csv"),
               "-o", str(fitted_path)]
    say = bench_run._say

    def interrupt(text: str) -> None:  # Ctrl-C as the fit's second candidate starts
        say(text)
        if text.startswith("study-like fit block 3 "):
            raise KeyboardInterrupt

    monkeypatch.setattr(bench_run, "_say", interrupt)
    assert main(command) == 130
    err = capsys.readouterr().err
    assert "the fit runs 3 blocks" in err and "then the validation 2 blocks" in err, err  # the estimate
    study_path = tmp_path / "v.study.csv"
    first = pd.read_csv(study_path)
    assert sorted(first["block"].unique()) == [0, 1]
    monkeypatch.setattr(bench_run, "_say", say)
    # Resumed with another model: refused in one line before the bench moves (its blocks would mix two).
    other_path = tmp_path / "other.json"
    save_model(fit_candidate(model, 11), other_path)
    assert main([*command[:2], str(other_path), *command[3:], "--resume"]) != 0
    err = capsys.readouterr().err
    assert "cannot resume" in err and "with another model" in err, err
    # Resumed: the fit's third block on, the two finished ones not run again.
    code = main([*command, "--resume"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "going on with unit 3" in captured.err and "fit block 1 of" not in captured.err, captured.err
    assert "fit block 2 of" not in captured.err and "fit block 3 of 5" in captured.err

    study = pd.read_csv(study_path)
    assert tuple(study.columns) == STUDY_COLUMNS
    blocks = study.groupby("block").first()
    assert list(blocks.index) == [0, 1, 2, 3, 4]  # each block once
    # The fit's paper block, its two candidates, then the validation's paper and dynamic blocks.
    assert list(blocks["fit"]) == [1, 1, 1, 0, 0]
    assert list(blocks["candidate"]) == [-1, *CANDIDATES, -1, -1]
    assert list(blocks["compensation"]) == [0, 1, 1, 0, 1]
    assert (study["support"] == 0.5).all() and (study["speed"] == 3).all()
    # The recording's first two blocks were kept as they were when the run stopped.
    pd.testing.assert_frame_equal(study[study["block"] <= 1].reset_index(drop=True), first)

    rmse_p, peak_p = _cost_terms(study[study["block"] == 0])
    costs = {}
    for block, candidate in ((1, CANDIDATES[0]), (2, CANDIDATES[1])):
        rmse, peak = _cost_terms(study[study["block"] == block])
        costs[candidate] = rmse / max(rmse_p, 1e-6) + max(peak, 0.0) / max(peak_p, 1.0)
    expected = min(costs, key=lambda k: costs[k])
    out = captured.out
    lines = out.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("candidate  drag scale"))
    rows = [line.split() for line in lines[start + 1:start + 1 + len(CANDIDATES)]]
    table = {int(fields[0]): float(fields[-1]) for fields in rows}  # candidate, drag, inertia, shift, cost
    assert table.keys() == set(CANDIDATES), out
    assert all(table[k] == pytest.approx(costs[k], abs=1e-3) for k in CANDIDATES), (table, costs)
    assert f"fitted: candidate {expected} " in out, out
    assert f"the fit chose candidate {expected} " in captured.err  # the validation ran it
    assert "50          V3     paper" in out and "50          V3     dynamic" in out and "recommended:" in out
    assert not (tmp_path / "v.latency.csv").exists()  # only the study-like strokes
    written = load_model(fitted_path).dynamic
    chosen = fit_candidate(model, expected).dynamic
    assert written is not None and chosen is not None
    assert (written.viscous_nm_s_rad, written.inertia_kg_m2, written.lowering) == \
        (chosen.viscous_nm_s_rad, chosen.inertia_kg_m2, chosen.lowering)

    # The recording alone gives the same fit again; judged without --fit it is refused, in one line.
    assert main(["bench", "validate", str(model_path), "--recording", str(study_path), "--fit"]) == 0
    assert f"fitted: candidate {expected} " in capsys.readouterr().out
    assert main(["bench", "validate", str(model_path), "--recording", str(study_path)]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "--fit" in err, err


def test_the_fit_s_candidates_are_the_batch_fit_s_grid():
    # The journal of a fit run keeps the grid its candidate numbers index.
    fit = StudyFit(grid=fit_grid(), speeds=("V3",))
    config = BenchRunConfig(fit=fit, identification=False)
    fingerprint = json.loads(json.dumps(config.protocol_fingerprint()))
    assert fingerprint["fit"]["grid"] == [list(point) for point in fit_grid()]
    assert fingerprint["fit"]["candidates"] == list(range(12)) and len(fit.blocks()) == 13
    drag, inertia, shift = fit_grid()[7]
    assert (drag, inertia, shift) == (1.4, 2.0, -0.05)  # drag outermost, then inertia, then the shift
    assert fit.repetitions == FIT_REPETITIONS  # the batch fit's
    with pytest.raises(ParameterError, match="candidates"):
        StudyFit(grid=fit_grid(), candidates=(0, 12))


class _StarvedOnce:
    """The bench's load cell, whose reader the host starves once for ``starve_s`` (from ``start``,
    monotonic time): its newest reading and its read attempts stand still meanwhile, as an
    ADS1115 reader thread's do when it is not scheduled (runtime/bench_cell.py)."""

    def __init__(self, cell, starve_s: float) -> None:
        self._cell, self.starve_s = cell, starve_s
        self.start = math.inf
        self._sample = self._counters = None

    def _starved(self) -> bool:
        return self.start <= time.monotonic() < self.start + self.starve_s and self._sample is not None

    @property
    def counters(self):
        if self._starved():
            return self._counters
        counters = self._cell.counters
        self._counters = SimpleNamespace(samples=counters.samples, io_errors=counters.io_errors,
                                         malformed=counters.malformed)
        return self._counters

    def read(self):
        if self._starved():
            return self._sample
        self._sample = self._cell.read()
        return self._sample

    def __getattr__(self, name):
        return getattr(self._cell, name)


def test_a_study_like_block_with_a_gap_in_the_load_cell_s_data_is_run_again(tmp_path):
    # Before, only identification strokes were run again: a study-like block kept the starved
    # reader's stale tension in its rows (and a fit judged a candidate on it).
    config = BenchRunConfig(identification=False, study=StudyStrokes(
        supports=(0.5,), speeds=("V3",), compensations=("paper",), repetitions=2))
    config = replace(config, safety=config.safety.on_shared_host())
    model = CompensationModel.from_friction(k=0.1)
    with open_sim_bench() as backend, \
            BenchRecordingWriter(tmp_path / "b.csv", config.protocol_fingerprint()) as writer:
        cell = _StarvedOnce(backend.load_cell, starve_s=0.45)

        def announce(text: str) -> None:  # the block's cycles start about 3.5 s after it is announced
            if cell.start == math.inf:
                cell.start = time.monotonic() + 5.0

        devices = BenchDevices(tdu=backend.motor, mannequin=backend.mannequin, imu=backend.imu,
                               load_cell=cell, clock=backend.clock)
        report = BenchRun(devices, config, writer, model_source=lambda *_: model, announce=announce).run()
    assert report.complete, report.fault
    assert report.data_gaps == 1
    study = pd.read_csv(tmp_path / "b.study.csv")
    assert study["block"].nunique() == 1
    # The block recorded is the second run, without a stale stretch: no tension held for 0.25 s.
    tension, times = study["tension_n"].to_numpy(), study["time_s"].to_numpy()
    changes = np.flatnonzero(np.diff(tension) != 0.0)
    held_s = np.diff(times[np.concatenate([[0], changes + 1, [len(times) - 1]])])
    assert held_s.max() < 0.25, held_s.max()
