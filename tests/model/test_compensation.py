import json
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bowden.errors import ModelFileError, ParameterError
from bowden.model import CompensationLine, CompensationModel, LineFitStats, Provenance
from bowden.model.model_file import load_model, model_to_dict, save_model


def make_model(**kwargs):
    defaults = dict(
        raising=CompensationLine(intercept_nm=0.08, slope_m=0.044),
        lowering=CompensationLine(intercept_nm=-0.02, slope_m=0.027),
    )
    defaults.update(kwargs)
    return CompensationModel(**defaults)


def test_blend_defining_property_paper_values():
    # docs/design.md, "Sigmoid sign": w(-1) = 0.01, w(+1) = 0.99, B = ln(99)/(v99 - M) = 4.595 s/rad.
    model = make_model()
    assert model.blend_weight(-1.0) == pytest.approx(0.01, abs=1e-12)
    assert model.blend_weight(1.0) == pytest.approx(0.99, abs=1e-12)
    assert model.blend_weight(0.0) == pytest.approx(0.5)
    assert model.blend_steepness_s_rad == pytest.approx(4.59512, abs=1e-5)


def test_papers_printed_b_would_blend_backwards():
    # The paper's printed B = ln(99)/(v01 - M) is negative: it would weight lowering while raising.
    m = 0.0
    printed_b = math.log(99) / (-1.0 - m)
    assert 1.0 / (1.0 + math.exp(-printed_b * (1.0 - m))) == pytest.approx(0.01)


@given(st.floats(-3.0, 0.0), st.floats(0.05, 3.0))
def test_blend_property_for_any_velocities(v01, width):
    model = make_model(blend_velocity_01_rad_s=v01, blend_velocity_99_rad_s=v01 + width)
    assert model.blend_weight(v01) == pytest.approx(0.01, abs=1e-9)
    assert model.blend_weight(v01 + width) == pytest.approx(0.99, abs=1e-9)


@given(st.floats(-50.0, 50.0), st.floats(-50.0, 50.0))
def test_blend_monotonic_bounded_and_no_overflow(a, b):
    model = make_model()
    lo, hi = min(a, b), max(a, b)
    assert 0.0 <= model.blend_weight(lo) <= model.blend_weight(hi) <= 1.0
    assert model.blend_weight(1e308) == 1.0
    assert model.blend_weight(-1e308) == 0.0


@given(st.floats(0.0, 150.0), st.floats(-5.0, 5.0))
def test_torque_between_the_two_lines(tension, velocity):
    model = make_model()
    low, high = model.lowering.torque_nm(tension), model.raising.torque_nm(tension)
    t = model.torque_nm(tension, velocity)
    assert min(low, high) - 1e-12 <= t <= max(low, high) + 1e-12


def test_torque_selects_lines_at_extremes():
    model = make_model()
    assert model.torque_nm(40.0, 10.0) == pytest.approx(0.08 + 0.044 * 40.0, rel=1e-9)
    assert model.torque_nm(40.0, -10.0) == pytest.approx(-0.02 + 0.027 * 40.0, rel=1e-9)


def test_from_friction_uses_the_single_bend_law():
    model = CompensationModel.from_friction(k=0.1, pulley_radius_m=0.035)
    assert model.raising.slope_m == pytest.approx(0.035 * 1.1 / 0.9)
    assert model.lowering.slope_m == pytest.approx(0.035 * 0.9 / 1.1)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"blend_velocity_01_rad_s": 1.0, "blend_velocity_99_rad_s": -1.0}, "must exceed"),
        ({"pulley_radius_m": 35.0}, "pulley_radius_m"),
        ({"blend_velocity_99_rad_s": math.nan}, "blend_velocity_99_rad_s"),
    ],
)
def test_invalid_models(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        make_model(**kwargs)
    with pytest.raises(ParameterError, match="slope_m"):
        CompensationLine(intercept_nm=0.0, slope_m=35.0)


def full_model():
    fit = LineFitStats(
        n=1200, r_squared_ols=0.994, r_squared_robust=0.995, robust_scale_nm=0.02,
        intercept_se_nm=0.003, slope_se_m=1e-4,
    )
    prov = Provenance(
        source_files=("bench.csv",), source_sha256=("ab" * 32,), created_utc="2026-11-21T00:00:00Z",
        tool="bowden identify", tool_version="0.1.0",
    )
    return make_model(raising_fit=fit, lowering_fit=fit, provenance=prov, blend_velocity_01_rad_s=-0.5)


def test_save_load_round_trip(tmp_path):
    model = full_model()
    path = tmp_path / "model.json"
    save_model(model, path)
    assert load_model(path) == model
    assert json.loads(path.read_text())["version"] == 2
    bare = make_model()
    save_model(bare, path)
    assert load_model(path) == bare


def write(tmp_path, data):
    path = tmp_path / "model.json"
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize(
    ("mutate", "field"),
    [
        (lambda d: d["raising"].pop("slope_m"), "raising.slope_m"),
        (lambda d: d["lowering"].__setitem__("intercept_nm", "0.1"), "lowering.intercept_nm"),
        (lambda d: d.__setitem__("version", 3), "version"),
        (lambda d: d.__setitem__("format", "other"), "format"),
        (lambda d: d["blend"].pop("velocity_99_rad_s"), "blend.velocity_99_rad_s"),
        (lambda d: d["raising"]["fit"].pop("n"), "raising.fit.n"),
        (lambda d: d["raising"]["fit"].__setitem__("n", 1.5), "raising.fit.n"),
        (lambda d: d.pop("pulley_radius_m"), "pulley_radius_m"),
        (lambda d: d["provenance"].__setitem__("source_files", "bench.csv"), "provenance.source_files"),
        (lambda d: d.pop("blend"), "blend"),
        (lambda d: d["raising"].__setitem__("slope_m", 3.5), "raising.slope_m"),
    ],
)
def test_bad_files_name_the_field(tmp_path, mutate, field):
    data = model_to_dict(full_model())
    mutate(data)
    with pytest.raises(ModelFileError, match=f"'{field}'"):
        load_model(write(tmp_path, data))


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(ModelFileError, match="bowden identify"):
        load_model(tmp_path / "absent.json")
    path = tmp_path / "broken.json"
    path.write_text('{"format": ')
    with pytest.raises(ModelFileError, match="not valid JSON"):
        load_model(path)
    path.write_text("[1, 2]")
    with pytest.raises(ModelFileError, match="JSON object"):
        load_model(path)
    inconsistent = model_to_dict(full_model())
    inconsistent["blend"]["velocity_01_rad_s"] = 2.0
    with pytest.raises(ModelFileError, match="must exceed"):
        load_model(write(tmp_path, inconsistent))
