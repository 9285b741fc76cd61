"""Every invalid value of a model.json is a ModelFileError naming the file and the dotted field."""

from __future__ import annotations

import copy
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from bowden.errors import ModelFileError
from bowden.model.compensation import CompensationLine, CompensationModel, LineFitStats, Provenance
from bowden.model.model_file import MAX_INTERCEPT_NM, load_model, model_from_dict, model_to_dict, save_model

FIT = LineFitStats(
    n=1200, r_squared_ols=0.98, r_squared_robust=0.97, robust_scale_nm=0.02, intercept_se_nm=0.004,
    slope_se_m=0.0003,
)
MODEL = CompensationModel(
    raising=CompensationLine(intercept_nm=0.05, slope_m=0.044),
    lowering=CompensationLine(intercept_nm=-0.02, slope_m=0.028),
    raising_fit=FIT,
    lowering_fit=FIT,
    provenance=Provenance(source_files=("bench.csv",), source_sha256=("0" * 64,), created_utc="2024-06-07",
                          tool="bowden identify", tool_version="0.1.0"),
)


def _changed(change: Callable[[dict[str, Any]], None]) -> dict[str, Any]:
    data = copy.deepcopy(model_to_dict(MODEL))
    change(data)
    return data


def _load(tmp_path: Path, data: dict[str, Any]) -> CompensationModel:
    path = tmp_path / "suit-model.json"
    path.write_text(json.dumps(data), encoding="utf-8")
    return load_model(path)


def _set(*keys: str, value: object) -> Callable[[dict[str, Any]], None]:
    def change(data: dict[str, Any]) -> None:
        target = data
        for key in keys[:-1]:
            target = target[key]
        target[keys[-1]] = value

    return change


@pytest.mark.parametrize(
    ("change", "field", "problem"),
    [
        (_set("version", value=True), "version", "must be the integer 1 or 2, got True"),
        (_set("version", value=1.0), "version", "must be the integer 1 or 2, got 1.0"),
        (_set("raising", "fit", "n", value=-5), "raising.fit.n", "must be a non-negative integer"),
        (_set("lowering", "fit", "n", value=2.5), "lowering.fit.n", "must be a non-negative integer"),
        (_set("raising", "fit", "r_squared_ols", value=3.0), "raising.fit.r_squared_ols",
         r"must be in \[0, 1\]"),
        (_set("lowering", "fit", "r_squared_robust", value=-0.2), "lowering.fit.r_squared_robust",
         r"must be in \[0, 1\]"),
        (_set("raising", "fit", "robust_scale_nm", value=-0.1), "raising.fit.robust_scale_nm",
         "must be >= 0"),
        (_set("raising", "fit", "slope_se_m", value=-1e-4), "raising.fit.slope_se_m", "must be >= 0"),
        (_set("raising", "intercept_nm", value=1e6), "raising.intercept_nm",
         r"is 1000000.0 Nm, beyond the motor's peak torque \(9 Nm\)"),
        (_set("lowering", "intercept_nm", value=-9.5), "lowering.intercept_nm",
         "is -9.5 Nm, beyond the motor's peak torque"),
        (_set("raising", "slope_m", value=0.01), "raising.slope_m",
         r"\(0.01 m\) must not be below lowering.slope_m \(0.028 m\): friction .* raising needs more motor "
         "torque"),
    ],
)
def test_invalid_values_name_the_file_and_the_field(
    tmp_path: Path, change: Callable[[dict[str, Any]], None], field: str, problem: str
) -> None:
    with pytest.raises(ModelFileError, match=rf"suit-model\.json: field '{field}' {problem}"):
        _load(tmp_path, _changed(change))


def test_the_fit_statistics_constructor_is_wrapped_too(monkeypatch: pytest.MonkeyPatch) -> None:
    # Whatever LineFitStats refuses (now or after a future rule) reaches the caller as a ModelFileError.
    import bowden.model.compensation as compensation

    def stricter(self: LineFitStats) -> None:
        raise compensation.ParameterError("slope_se_m must be below 1")

    monkeypatch.setattr(compensation.LineFitStats, "__post_init__", stricter)
    with pytest.raises(ModelFileError, match=r"model\.json: field 'raising\.fit' is invalid: slope_se_m"):
        model_from_dict(model_to_dict(MODEL), source="model.json")


def test_a_valid_model_and_the_bounds_themselves_load(tmp_path: Path) -> None:
    assert _load(tmp_path, model_to_dict(MODEL)) == MODEL

    def edges(data: dict[str, Any]) -> None:
        data["raising"]["intercept_nm"] = MAX_INTERCEPT_NM
        data["lowering"]["intercept_nm"] = -MAX_INTERCEPT_NM
        data["raising"]["fit"]["r_squared_ols"] = 1.0 + 1e-12  # an exact fit, rounded
        data["lowering"]["fit"]["r_squared_robust"] = 0.0
        data["lowering"]["fit"]["n"] = 0

    loaded = _load(tmp_path, _changed(edges))
    assert loaded.raising.intercept_nm == 9.0 and loaded.lowering.intercept_nm == -9.0
    assert loaded.lowering_fit is not None and loaded.lowering_fit.n == 0


@pytest.mark.parametrize("k", [0.12, 0.0])  # 0: a frictionless transmission, equal slopes
def test_the_ideal_friction_model_round_trips(tmp_path: Path, k: float) -> None:
    model = CompensationModel.from_friction(k=k)
    save_model(model, tmp_path / "model.json")
    assert load_model(tmp_path / "model.json") == model
