"""``bowden analyze`` in the test's own process, for tests that analyse a handful of trials.

The command's default engine spawns one worker process per core, each importing the analysis and
loading its compiled kernels: on two cores that costs about 10 s of wall time (twice the analysis of
five short trials in this process), paid again by every test that calls it. The results do not
depend on the engine (``bowden.study.analyze.analyze_store``; tests/study/test_parallel_study.py
checks that), so a test that checks what the report or the store says runs the analysis here.
"""

from __future__ import annotations

import pytest

import bowden.study.analyze
from bowden.engine.pool import study_engine


def analyze_in_process(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make ``bowden analyze`` (``analyze_store`` without ``workers``) run in this process."""
    monkeypatch.setattr(
        bowden.study.analyze, "study_engine", lambda workers=None: study_engine(workers or 1)
    )
