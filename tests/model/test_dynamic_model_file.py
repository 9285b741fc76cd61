"""model.json version 2 holds the dynamic compensation; version 1 files still load."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bowden.errors import ModelFileError, ParameterError
from bowden.model import CompensationLine, CompensationModel
from bowden.model.dynamic import DynamicCompensation, DynamicFitStats
from bowden.model.model_file import load_model, model_to_dict, save_model

DYNAMIC = DynamicCompensation(
    raising=CompensationLine(intercept_nm=0.08, slope_m=0.043),
    lowering=CompensationLine(intercept_nm=-0.08, slope_m=0.029),
    viscous_nm_s_rad=0.042,
    inertia_kg_m2=1.0e-3,
    imu_latency_s=0.04,
    fit=DynamicFitStats(
        n=9000,
        viscous_se_nm_s_rad=1e-5,
        inertia_se_kg_m2=2e-5,
        regime_rms_nm=(("steady raising", 0.005), ("turns", 0.3)),
        paper_rms_nm=(("steady raising", 0.03), ("turns", 0.31)),
    ),
)
MODEL = CompensationModel(
    raising=CompensationLine(intercept_nm=0.11, slope_m=0.043),
    lowering=CompensationLine(intercept_nm=-0.11, slope_m=0.029),
    dynamic=DYNAMIC,
)


def write(tmp_path: Path, data: dict) -> Path:
    path = tmp_path / "model.json"
    path.write_text(json.dumps(data))
    return path


def test_version_2_round_trips_the_dynamic_part(tmp_path: Path) -> None:
    save_model(MODEL, tmp_path / "model.json")
    data = json.loads((tmp_path / "model.json").read_text())
    assert data["version"] == 2 and data["dynamic"]["viscous_nm_s_rad"] == 0.042
    loaded = load_model(tmp_path / "model.json")
    assert loaded == MODEL and loaded.recommended_compensation == "dynamic"


def test_a_version_1_file_loads_with_the_paper_lines_only(tmp_path: Path) -> None:
    data = model_to_dict(MODEL)
    data["version"] = 1
    del data["dynamic"]
    loaded = load_model(write(tmp_path, data))
    assert loaded.dynamic is None and loaded.recommended_compensation == "paper"
    assert loaded.raising == MODEL.raising


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda d: d["dynamic"].pop("viscous_nm_s_rad"), "dynamic.viscous_nm_s_rad"),
        (lambda d: d["dynamic"].__setitem__("inertia_kg_m2", "1e-3"), "dynamic.inertia_kg_m2"),
        (lambda d: d["dynamic"]["raising"].__setitem__("slope_m", 2.0), "dynamic.raising.slope_m"),
        (lambda d: d["dynamic"].__setitem__("viscous_nm_s_rad", -0.1), "dynamic"),
        (lambda d: d["dynamic"]["fit"].__setitem__("n", 1.5), "dynamic.fit.n"),
        (
            lambda d: d["dynamic"]["fit"]["regime_rms_nm"].__setitem__("turns", "x"),
            "dynamic.fit.regime_rms_nm.turns",
        ),
        (lambda d: d.__setitem__("dynamic", [1]), "dynamic"),
    ],
)
def test_a_bad_dynamic_field_is_named(tmp_path: Path, change, field: str) -> None:
    data = model_to_dict(MODEL)
    change(data)
    with pytest.raises(ModelFileError, match=f"'{field}'"):
        load_model(write(tmp_path, data))


def test_the_dynamic_parameters_are_checked() -> None:
    with pytest.raises(ParameterError, match="imu_latency_s"):
        DynamicCompensation(
            raising=DYNAMIC.raising,
            lowering=DYNAMIC.lowering,
            viscous_nm_s_rad=0.0,
            inertia_kg_m2=0.0,
            imu_latency_s=0.5,
        )
    with pytest.raises(ParameterError, match="raising slope"):
        DynamicCompensation(
            raising=DYNAMIC.lowering, lowering=DYNAMIC.raising, viscous_nm_s_rad=0.0, inertia_kg_m2=0.0
        )
    # The friction law for figures: Coulomb jump at zero, then drag on either side.
    assert DYNAMIC.friction_nm(30.0, 0.0) == 0.0
    jump = DYNAMIC.friction_nm(30.0, 1e-9) - DYNAMIC.friction_nm(30.0, -1e-9)
    assert jump == pytest.approx(DYNAMIC.raising.torque_nm(30.0) - DYNAMIC.lowering.torque_nm(30.0), rel=1e-6)
    assert DYNAMIC.friction_nm(30.0, 2.0) - DYNAMIC.friction_nm(30.0, 1.0) == pytest.approx(0.042)


def test_a_dynamic_compensation_not_recommended_leaves_the_controller_on_the_papers_lines(
    tmp_path: Path,
) -> None:
    from dataclasses import replace

    from bowden.control import build_controller
    from bowden.model import Subject

    why = "at V3 the dynamic compensation's RMSE 9.50 N does not beat the paper's 7.30 N"
    path = tmp_path / "model.json"
    save_model(replace(MODEL, dynamic=replace(DYNAMIC, recommended=False, recommendation=why)), path)
    loaded = load_model(path)
    assert loaded.dynamic is not None
    assert (loaded.dynamic.recommended, loaded.dynamic.recommendation) == (False, why)
    subject = Subject(height_m=1.70, mass_kg=63.0, sex="female")
    assert build_controller(model=path, support=0.5, subject=subject).compensation == "paper"
    forced = build_controller(model=path, support=0.5, subject=subject, compensation="dynamic")
    assert forced.compensation == "dynamic"
    # A file written before the recommendation existed keeps recommending the dynamic compensation.
    data = model_to_dict(MODEL)
    del data["dynamic"]["recommended"], data["dynamic"]["recommendation"]
    old = write(tmp_path, data)
    assert build_controller(model=old, support=0.5, subject=subject).compensation == "dynamic"
    data["dynamic"]["recommended"] = "no"
    with pytest.raises(ModelFileError, match=r"dynamic\.recommended"):
        load_model(write(tmp_path, data))


def test_the_recommendation_per_support_and_speed_is_stored_and_picks_the_controllers_compensation(
    tmp_path: Path,
) -> None:
    from dataclasses import replace

    from bowden.control import build_controller
    from bowden.model import Subject

    cells = (("pretension", "V1", True), ("pretension", "V3", False), ("50", "V1", True), ("50", "V3", True))
    path = tmp_path / "model.json"
    save_model(replace(MODEL, dynamic=replace(DYNAMIC, recommended=False, recommended_cells=cells)), path)
    assert json.loads(path.read_text())["dynamic"]["recommended_cells"][1] == {
        "support": "pretension", "speed": "V3", "dynamic": False}
    loaded = load_model(path)
    assert loaded.dynamic is not None and loaded.dynamic.recommended_cells == cells
    subject = Subject(height_m=1.70, mass_kg=63.0, sex="female")

    def chosen(support: float | str, speed: str | None) -> str:
        return build_controller(model=path, support=support, subject=subject,  # type: ignore[arg-type]
                                speed=speed).compensation

    assert (chosen("pretension", "V1"), chosen("pretension", "V3")) == ("dynamic", "paper")
    assert (chosen(0.5, "V3"), chosen(0.5, None)) == ("dynamic", "dynamic")
    assert chosen("pretension", None) == "paper"  # speed unknown: it lost at one speed of this support
    assert chosen(0.25, "V1") == "paper"  # a support the bench did not measure: `recommended`
    # A file without the cells (before the per-cell rule) loads, with `recommended` for every cell.
    assert "recommended_cells" not in model_to_dict(MODEL)["dynamic"]
    data = model_to_dict(MODEL)
    data["dynamic"]["recommended_cells"] = [{"support": 50, "speed": "V1", "dynamic": True}]
    with pytest.raises(ModelFileError, match=r"dynamic\.recommended_cells\[0\]"):
        load_model(write(tmp_path, data))
