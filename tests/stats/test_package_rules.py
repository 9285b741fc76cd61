"""Package rules of bowden.stats: executed docstring examples and docs/design.md's forbidden imports."""

from __future__ import annotations

import doctest
import importlib
import re
from pathlib import Path

import pytest

import bowden.stats

STATS_DIR = Path(bowden.stats.__file__).parent
MODULES = sorted(f"bowden.stats.{p.stem}" for p in STATS_DIR.glob("*.py") if p.stem != "__init__")


@pytest.mark.parametrize("module", ["bowden.stats", *MODULES])
def test_docstring_examples_run(module: str) -> None:
    result = doctest.testmod(importlib.import_module(module), optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0


def test_stats_imports_no_hardware_runtime_sim_web_or_study() -> None:
    forbidden = re.compile(r"^\s*(from|import)\s+bowden\.(hardware|runtime|sim|web|study)\b", re.MULTILINE)
    offenders = [p.name for p in STATS_DIR.glob("*.py") if forbidden.search(p.read_text())]
    assert offenders == []
