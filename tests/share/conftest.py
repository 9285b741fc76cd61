"""A small simulated study made once per process (shared with tests/study), and the BIDS validator."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from tests.study.reduced_study import AnalyzeExport, analyze_export, reduced_study

Validate = Callable[[Path], list[dict[str, Any]]]


@pytest.fixture(scope="session")
def small_study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The directory of the reduced study tests/study shares (tests/study/reduced_study.py): made once
    per process for both directories."""
    return reduced_study(tmp_path_factory).directory


@pytest.fixture(scope="session")
def small_study_export(tmp_path_factory: pytest.TempPathFactory) -> AnalyzeExport:
    """``bowden analyze --export DIR --format csv`` of :func:`small_study`, run once per process."""
    return analyze_export(tmp_path_factory)


def _validator() -> str:
    """The ``bids-validator-deno`` executable of this environment (a dev dependency)."""
    beside = Path(sys.executable).with_name("bids-validator-deno")
    found = str(beside) if beside.exists() else shutil.which("bids-validator-deno")
    assert found, "bids-validator-deno is a dev dependency: pip install -e '.[dev]'"
    return found


def validation_errors(dataset: Path) -> list[dict[str, Any]]:
    """Every issue of severity ``error`` the official validator reports, every row of every TSV checked."""
    return [issue for issue in validator_issues(dataset) if issue.get("severity") == "error"]


def validator_issues(dataset: Path) -> list[dict[str, Any]]:
    """Every issue the official validator reports (errors and warnings)."""
    run = subprocess.run(
        [_validator(), "--format", "json", "--max-rows", "-1", str(dataset)],
        capture_output=True, text=True, timeout=240, check=False,
    )
    issues = json.loads(run.stdout)["issues"]["issues"]
    assert isinstance(issues, list)
    return issues


@pytest.fixture(scope="session")
def bids_errors() -> Validate:
    return validation_errors
