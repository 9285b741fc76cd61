"""The reduced simulated study and its ``bowden analyze --export``, made once per test process.

Several test files read the same small study: tests/study/test_pipeline.py (end to end),
tests/study/test_parallel_study.py (its single-process run), tests/share/test_r_script.py (its GLMMs
refitted in R) and tests/share/test_bids_export.py (its BIDS export). Each made its own, about 10 s
of CPU a study and as much again an analysis; their fixtures (tests/study/conftest.py,
tests/share/conftest.py) now take it from here. A session fixture belongs to its directory's
conftest, so the one study is kept in this module (imported once per process as
``tests.study.reduced_study``), under the session's base temporary directory.

The tests that use it only read it, or run what leaves its results as they are (a resumed run, the
analysis again, a refused run with other settings).
"""

from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass
from pathlib import Path

import pytest

from bowden.cli import main
from bowden.study.pipeline import StudyResult, StudySettings, run_study

# The size: 2 participants, 1 repetition per trial (which the analysis then keeps: the
# paper's dropped first repetition is the only one); 2 × 4 conditions × 3 speeds = 24 trials.
SETTINGS = StudySettings(participants=2, repetitions=1, quick_bench=True, seed=4)
N_TRIALS = 24


@dataclass(frozen=True)
class AnalyzeExport:
    """What ``bowden analyze STUDY --export DIR --format csv --report FILE --quiet --workers 1`` left."""

    code: int
    stdout: str
    report: Path
    tables: Path


_made: dict[str, object] = {}


def reduced_study(tmp_path_factory: pytest.TempPathFactory) -> StudyResult:
    """:data:`SETTINGS` run in this process (``workers=1``: the same results, no worker processes)."""
    if "study" not in _made:
        _made["study"] = run_study(SETTINGS, tmp_path_factory.mktemp("reduced") / "study", workers=1)
    result = _made["study"]
    assert isinstance(result, StudyResult)
    return result


def analyze_export(tmp_path_factory: pytest.TempPathFactory) -> AnalyzeExport:
    """``bowden analyze --export`` of :func:`reduced_study` to CSV, analysed in this process (``--workers 1``:
    the same results, tests/study/test_parallel_study.py, and no worker to spawn)."""
    if "export" not in _made:
        study = reduced_study(tmp_path_factory)
        out = tmp_path_factory.mktemp("reduced_export")
        report, tables = out / "report.html", out / "tables"
        stdout = io.StringIO()
        with contextlib.redirect_stdout(stdout):
            code = main(["analyze", str(study.directory), "--export", str(tables), "--format", "csv",
                         "--quiet", "--report", str(report), "--workers", "1"])
        _made["export"] = AnalyzeExport(code=code, stdout=stdout.getvalue(), report=report, tables=tables)
    export = _made["export"]
    assert isinstance(export, AnalyzeExport)
    return export
