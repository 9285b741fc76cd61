"""The EMG pipeline computes what it computed before (tests/fixtures/emg_pipeline.npz, at 1e-9).

The fixture was written by scripts/make_emg_pipeline_fixture.py before the pipeline was optimised;
this recomputes every pinned output (the paper's chain with ECG removal and its variants, the plain
steps, R-peaks) on the same generated inputs. Samples and block sums are compared at rtol 1e-9 and
atol 1e-9 of the stored array's largest magnitude; R-peak indices exactly.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

_ROOT = Path(__file__).resolve().parents[2]
_TOLERANCE = 1e-9


def _maker() -> ModuleType:
    spec = importlib.util.spec_from_file_location(
        "make_emg_pipeline_fixture", _ROOT / "scripts" / "make_emg_pipeline_fixture.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def recomputed() -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    maker = _maker()
    with np.load(maker.FIXTURE) as stored:
        expected = {key: stored[key] for key in stored.files}
    return expected, maker.outputs()


def test_fixture_inputs_are_regenerated_exactly(
    recomputed: tuple[dict[str, np.ndarray], dict[str, np.ndarray]],
) -> None:
    expected, actual = recomputed
    inputs = sorted(key for key in expected if "/input/" in key)
    assert inputs and inputs == sorted(key for key in actual if "/input/" in key)
    for key in inputs:
        np.testing.assert_allclose(actual[key], expected[key], rtol=1e-12, atol=0.0, err_msg=key)


def test_emg_pipeline_outputs_identical_to_before(
    recomputed: tuple[dict[str, np.ndarray], dict[str, np.ndarray]],
) -> None:
    expected, actual = recomputed
    assert sorted(actual) == sorted(expected)
    for key in sorted(expected):
        stem, part = key.rsplit("/", 1)
        if "/input/" in key or part == "scale":
            continue
        want, got = expected[key], actual[key]
        assert got.shape == want.shape, key
        if part == "peaks":
            np.testing.assert_array_equal(got, want, err_msg=key)
            continue
        # A block sum moves by as much as one of its samples: compare it at the samples' tolerance.
        scale = float(expected[f"{stem}/scale"]) ** (2 if part == "sum_sq" else 1)
        rtol = 0.0 if part in ("sum", "sum_sq") else _TOLERANCE
        np.testing.assert_allclose(got, want, rtol=rtol, atol=_TOLERANCE * scale, err_msg=key)
