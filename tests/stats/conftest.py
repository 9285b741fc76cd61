"""Shared fixtures: the committed data sets and R's reference outputs (tests/fixtures/stats)."""

from __future__ import annotations

import json
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from bowden.stats import GlmmOptions, GlmmResult, fit_gamma_glmm

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "stats"
DATASETS = ("balanced", "unbalanced")


@cache
def _reference() -> dict[str, Any]:
    return dict(json.loads((FIXTURES / "reference_glmm.json").read_text()))


@cache
def _dataset(name: str) -> pd.DataFrame:
    return pd.read_csv(FIXTURES / f"gamma_{name}.csv")


@cache
def _fitted(name: str, method: str) -> GlmmResult:
    return fit_gamma_glmm(_dataset(name), options=GlmmOptions(method=method))  # type: ignore[arg-type]


@pytest.fixture(params=DATASETS)
def dataset_name(request: pytest.FixtureRequest) -> str:
    return str(request.param)


# Test modules cannot import this file under --import-mode=importlib: the cached loaders are fixtures.
@pytest.fixture(scope="session")
def reference() -> dict[str, Any]:
    """R's reference outputs (reference_glmm.json)."""
    return _reference()


@pytest.fixture(scope="session")
def dataset() -> Callable[[str], pd.DataFrame]:
    """Loader of a committed data set by name (``balanced`` or ``unbalanced``)."""
    return _dataset


@pytest.fixture(scope="session")
def fitted() -> Callable[[str, str], GlmmResult]:
    """Cached fit of a data set by a method name."""
    return _fitted
