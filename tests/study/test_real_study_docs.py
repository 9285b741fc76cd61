"""docs/study.md, "A real study, end to end": its commands, run as written on the simulated suit.

The section's first block is what a lab types on the real suit. Here it runs with ``--backend sim``
instead of ``can``, a command trigger that logs each edge on the host clock instead of the GPIO line,
and the amplifier's EDF written from those edges (SAGA-shaped: UNI1..UNI8 in µV, a negative-logic
TRIGGERS channel, STATUS): three short trials, the import and the report, so the documented path
cannot rot.
"""

from __future__ import annotations

import itertools
import shlex
import sys
from pathlib import Path

import edfio
import numpy as np
import pytest

from bowden.cli import main
from bowden.model import CompensationModel
from bowden.model.model_file import save_model

DOC = Path(__file__).parents[2] / "docs" / "study.md"
TRIGGER_LOG = Path(__file__).parents[1] / "runtime" / "trigger_log.py"
RATE_HZ = 2000.0


def documented_commands() -> list[list[str]]:
    """The first ``sh`` block of the section, one argument list per command."""
    section = DOC.read_text(encoding="utf-8").split("## A real study, end to end", 1)[1].split("\n## ", 1)[0]
    block = section.split("```sh\n", 1)[1].split("```", 1)[0]
    return [shlex.split(line) for line in block.replace("\\\n", " ").splitlines() if line.strip()]


def replace_option(argv: list[str], option: str, value: str | None) -> list[str]:
    """``argv`` with ``option``'s value replaced (None: the option removed with its value)."""
    assert option in argv, f"docs/study.md's command no longer has {option}: {shlex.join(argv)}"
    at = argv.index(option)
    return [*argv[:at], *([option, value] if value is not None else []), *argv[at + 2 :]]


def write_amplifier_edf(path: Path, edges_host_s: list[tuple[int, float]]) -> None:
    """What a SAGA recorded: noise-like sEMG on UNI1..UNI8 and bowden's line on TRIGGERS (idle high)."""
    start = edges_host_s[0][1] - 3.0
    n = int((edges_host_s[-1][1] + 3.0 - start) * RATE_HZ) // int(RATE_HZ) * int(RATE_HZ)
    trigger = np.ones(n)
    for (level, time_s), (_, next_s) in itertools.pairwise(edges_host_s):
        if level == 1:
            trigger[int(np.ceil((time_s - start) * RATE_HZ)) : int(np.ceil((next_s - start) * RATE_HZ))] = 0.0
    rng = np.random.default_rng(4)
    signals = [
        edfio.EdfSignal(30.0 * rng.standard_normal(n), RATE_HZ, label=f"UNI{i + 1}", physical_dimension="uV",
                        physical_range=(-2000.0, 2000.0))
        for i in range(8)
    ]
    signals.append(edfio.EdfSignal(trigger, RATE_HZ, label="TRIGGERS", physical_range=(0.0, 1.0)))
    signals.append(edfio.EdfSignal(np.zeros(n), RATE_HZ, label="STATUS", physical_range=(0.0, 100.0)))
    edfio.Edf(signals, data_record_duration=1.0).write(path)


def test_the_documented_real_study_runs_on_the_simulated_suit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run, emg_import, analyze = documented_commands()
    assert run[:2] == ["bowden", "run"] and emg_import[:3] == ["bowden", "emg", "import"]
    assert analyze[:2] == ["bowden", "analyze"]
    store, edf, levels = tmp_path / "study.db", tmp_path / "P07_session.edf", tmp_path / "edges.txt"
    save_model(CompensationModel.from_friction(k=0.1), tmp_path / "model.json")
    trial = replace_option(run[1:], "--backend", "sim")
    trial = replace_option(trial, "--model", str(tmp_path / "model.json"))
    trial = replace_option(trial, "--record", str(store))
    trial = replace_option(trial, "--trigger", f"command:{sys.executable} {TRIGGER_LOG} {levels} {{level}}")
    trial = replace_option(trial, "--lsl", None) if "--lsl" in trial else trial
    for condition in ("support_50", "pretension", "no_suit"):
        # One V3 repetition (5/3 s) after 0.2 s of rest: what the import and the report need.
        # The simulated suit shares this host, and the test times no watchdog: relaxed as the web
        # tests' (an idle three-worker run stopped the pretension trial once, exit 3, 2026-11-28).
        argv = [*replace_option(trial, "--condition", condition), "--duration", "2", "--lead-in", "0.2",
                "--speed", "V3", "--imu-max-age-ms", "500", "--motor-silence-ms", "500",
                "--host-stall-ms", "1000"]
        code, said = main(argv), capsys.readouterr()
        # This trial's summary lines only: the whole output, shown as it was, came out truncated
        # before the line that said why a trial once stopped with exit 3.
        summary = [line for line in (said.out + said.err).splitlines()
                   if line.startswith(("stopped:", "health:", "loop timing:", "bowden:"))]
        assert code == 0, (condition, summary)

    edges = [(int(level), float(time_s)) for level, time_s in
             (line.split() for line in levels.read_text(encoding="utf-8").splitlines())]
    assert [level for level, _ in edges] == [1, 0] * 3
    write_amplifier_edf(edf, edges)
    files = {"study.db": str(store), "P07_session.edf": str(edf)}
    assert main([files.get(arg, arg) for arg in emg_import[1:]]) == 0, capsys.readouterr().err
    report = tmp_path / "report.html"
    analysed = replace_option([files.get(arg, arg) for arg in analyze[1:]], "--report", str(report))
    assert main([*analysed, "--quiet"]) == 0, capsys.readouterr().err
    assert "analysed 3 trials;" in capsys.readouterr().out
    html = report.read_text(encoding="utf-8")
    assert "imported from P07_session.edf" in html and "Trials" in html
