"""The reduced study shared by this directory's and tests/share's tests (tests/study/reduced_study.py)."""

from __future__ import annotations

import pytest
from tests.study.reduced_study import AnalyzeExport, analyze_export, reduced_study

from bowden.study.pipeline import StudyResult


@pytest.fixture(scope="session")
def shared_study(tmp_path_factory: pytest.TempPathFactory) -> StudyResult:
    """The reduced study (2 participants, 1 repetition, quick bench, seed 4), made once per process."""
    return reduced_study(tmp_path_factory)


@pytest.fixture(scope="session")
def shared_export(tmp_path_factory: pytest.TempPathFactory) -> AnalyzeExport:
    """``bowden analyze --export DIR --format csv`` of :func:`shared_study`, run once per process."""
    return analyze_export(tmp_path_factory)
