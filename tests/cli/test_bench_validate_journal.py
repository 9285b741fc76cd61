"""``bench validate`` reads the journal of a bench run: a ``--recording`` of another model is refused,
and a ``--resume``'s estimate is of the blocks left (no bench moves here: the run is stubbed out)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import bowden.cli._bench_validate as bench_validate
from bowden.cli import main
from bowden.model import CompensationModel
from bowden.model.model_file import save_model
from bowden.model.model_record import controller_sha256
from bowden.runtime.bench_config import BenchRunConfig
from bowden.runtime.bench_recording import STUDY_COLUMNS, BenchRecordingWriter
from bowden.runtime.bench_segments import study_time_s


def _journal(recording: Path, protocol: dict[str, object], units_done: int) -> None:
    """A bench run's recording and journal with ``units_done`` units recorded (one stroke's rows)."""
    n = 20
    t = np.arange(n) * 0.005
    rows = np.column_stack([t, np.full(n, 0.5), np.full(n, 2.0), np.full(n, 20.0), np.full(n, 1.0),
                            np.zeros(n)])
    log = np.column_stack([t, np.zeros(n), np.ones(n), *np.zeros((7, n))])
    with BenchRecordingWriter(recording, protocol) as writer:
        writer.write_stroke(rows, log, strokes_done=units_done)


def _study_file(path: Path) -> None:
    """A study-like segment at 25 % V2: the paper's block 4 N off the law, the dynamic's 1 N."""
    blocks = []
    for block, error_n in enumerate((4.0, 1.0)):
        phase = np.linspace(0.0, 3.0, 3000, endpoint=False)
        frame = pd.DataFrame(0.0, index=np.arange(phase.size), columns=list(STUDY_COLUMNS))
        frame["cycle_phase"], frame["law_tension_n"] = phase, 20.0
        frame["tension_n"] = 20.0 + error_n
        frame["block"], frame["support"], frame["speed"], frame["compensation"] = block, 0.25, 2, block
        blocks.append(frame)
    pd.concat(blocks).to_csv(path, index=False)


def test_a_recording_of_another_model_is_refused_in_one_line(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    ran, other = CompensationModel.from_friction(k=0.1), CompensationModel.from_friction(k=0.12)
    ran_path, other_path = tmp_path / "ran.json", tmp_path / "other.json"
    save_model(ran, ran_path)
    save_model(other, other_path)
    study = tmp_path / "v.study.csv"
    _study_file(study)
    # Without a journal beside it the model cannot be told: judged, and said so in one line.
    assert main(["bench", "validate", str(other_path), "--recording", str(study)]) == 0
    captured = capsys.readouterr()
    assert "25          V2     dynamic" in captured.out
    assert captured.err.count("\n") == 1 and "could not be checked" in captured.err, captured.err
    # A journal from `bench run` keeps no model: the same.
    _journal(tmp_path / "v.csv", {"study": "bench run"}, 1)
    assert main(["bench", "validate", str(other_path), "--recording", str(study)]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "could not be checked" in err and "v.csv.journal" in err, err
    # `bench validate`'s journal keeps the model its blocks ran: another is refused, that one judged.
    (tmp_path / "v.csv.journal").unlink()
    (tmp_path / "v.csv").unlink()
    (tmp_path / "v.log.csv").unlink()
    _journal(tmp_path / "v.csv", {"model": controller_sha256(ran)}, 1)
    assert main(["bench", "validate", str(other_path), "--recording", str(study)]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and "--recording" in captured.err and "MODEL" in captured.err
    assert "another model" in captured.err and controller_sha256(ran)[:12] in captured.err
    assert main(["bench", "validate", str(ran_path), "--recording", str(study)]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and "recommended:" in captured.out


def test_a_resumed_fit_estimates_the_blocks_left(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    from dataclasses import replace

    from bowden.identify.study_fit import fit_grid
    from bowden.model.dynamic import DynamicCompensation

    base = CompensationModel.from_friction(k=0.1)
    model = replace(base, dynamic=DynamicCompensation(raising=base.raising, lowering=base.lowering,
                                                      viscous_nm_s_rad=0.05, inertia_kg_m2=1.5e-3))
    model_path, output = tmp_path / "model.json", tmp_path / "v.csv"
    save_model(model, model_path)
    configs: list[BenchRunConfig] = []

    def stopped(args: object, config: BenchRunConfig, **_: object) -> int:  # the bench, stopped at once
        configs.append(config)
        return 130

    monkeypatch.setattr(bench_validate, "run_bench_config", stopped)
    command = ["bench", "validate", str(model_path), "--backend", "sim-wire", "--fit",
               "--bench-output", str(output)]
    assert main(command) == 130
    config = configs[0]
    blocks = config.study_blocks()
    assert len(blocks) == (len(fit_grid()) + 1) * 3 + 3 * 3 * 2  # the fit's 39 blocks, the validation's 18
    whole = study_time_s(blocks) / 60
    assert f"about {whole:.0f} min in all" in capsys.readouterr().err
    # 30 blocks recorded (all but the fit's last nine), then resumed: what is left, not the whole run.
    _journal(output, config.protocol_fingerprint(), 30)
    assert main([*command, "--resume"]) == 130
    err = capsys.readouterr().err
    left = study_time_s(blocks[30:]) / 60
    assert f"{left:.0f}" != f"{whole:.0f}"
    assert "resumed with 30 of 57 blocks done" in err, err
    assert re.search(rf"the fit's 9 blocks left, about \d+ min; then the validation 18 blocks, "
                     rf"about \d+ min; about {left:.0f} min left", err), err
