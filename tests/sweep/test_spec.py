"""Sweep specs: the grid, point ids, the blend parametrisations, TOML, and every refusal."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from bowden.errors import ParameterError
from bowden.sim.parameters import SuitParameters
from bowden.sweep import SweepSpec, preset
from bowden.sweep import axes as ax
from bowden.sweep import spec as spec_module


def test_grid_is_the_product_of_the_axes_times_the_seeds():
    spec = SweepSpec(
        axes=((ax.SHEATH_KINETIC, (0.1, 0.14, 0.18)), (ax.TORQUE_CONSTANT_RATIO, (0.85, 1.15))),
        seeds=(0, 7),
    )
    points = spec.points()
    assert len(points) == 3 * 2 * 2
    assert [p.mapping for p in points[:2]] == [
        {ax.SHEATH_KINETIC: 0.1, ax.TORQUE_CONSTANT_RATIO: 0.85},
        {ax.SHEATH_KINETIC: 0.1, ax.TORQUE_CONSTANT_RATIO: 1.15},
    ]
    assert {p.seed for p in points[:6]} == {0} and {p.seed for p in points[6:]} == {7}
    # Ids: distinct per point, one configuration per pair of seeds, stable across constructions.
    assert len({p.point_id for p in points}) == 12
    assert len({p.config_id for p in points}) == 6
    assert [p.config_id for p in points[:6]] == [p.config_id for p in points[6:]]
    again = SweepSpec(
        axes=((ax.SHEATH_KINETIC, (0.1, 0.14, 0.18)), (ax.TORQUE_CONSTANT_RATIO, (0.85, 1.15))),
        seeds=(0, 7),
    )
    assert [p.point_id for p in again.points()] == [p.point_id for p in points]


def test_point_ids_change_with_anything_that_changes_results():
    base = SweepSpec(axes=((ax.BLEND_99, (1.0,)),))
    ids = {base.points()[0].point_id}
    for change in (
        {"participants": 5},
        {"repetitions": 3},
        {"speeds": ("V1",)},
        {"conditions": ("support_50",)},
        {"identification": "nominal"},
        {"bench": "quick"},
        {"seeds": (1,)},
        {"axes": ((ax.BLEND_99, (0.5,)),)},
    ):
        ids.add(SweepSpec(**{"axes": base.axes, **change}).points()[0].point_id)
    assert len(ids) == 9


def test_blend_from_width_and_centre_is_hand_derived():
    # θ̇₀₀₁ = M − W/2, θ̇₀₉₉ = M + W/2.
    assert ax.blend_velocities({ax.BLEND_WIDTH: 0.5, ax.BLEND_CENTER: 0.1}) == pytest.approx((-0.15, 0.35))
    assert ax.blend_velocities({ax.BLEND_WIDTH: 0.5}) == pytest.approx((-0.25, 0.25))
    assert ax.blend_velocities({ax.BLEND_CENTER: 0.3}) == pytest.approx((-0.7, 1.3))
    assert ax.blend_velocities({ax.BLEND_99: 0.2}) == (-1.0, 0.2)
    assert ax.blend_velocities({}) == (-1.0, 1.0)  # the paper's blend


def test_combinations_with_an_inverted_blend_are_left_out_and_counted():
    spec = SweepSpec(axes=((ax.BLEND_01, (-0.5, 0.0, 0.5)), (ax.BLEND_99, (0.0, 1.0))))
    kept = [p.blend_velocities for p in spec.points()]
    assert kept == [(-0.5, 0.0), (-0.5, 1.0), (0.0, 1.0), (0.5, 1.0)]
    assert spec.skipped_combinations == 2


def test_shipped_blend_velocity_preset():
    spec = preset("blend-velocity")
    points = spec.points()
    assert len(points) == 7 * 6 - 3 and spec.skipped_combinations == 3
    assert all(low < high for low, high in (p.blend_velocities for p in points))
    assert (-1.0, 1.0) in [p.blend_velocities for p in points]  # the paper's blend is the baseline
    assert spec.participants == 17 and spec.repetitions == 10
    assert spec.conditions == ("pretension", "support_25", "support_50")


def test_plant_axes_reach_the_simulated_suit():
    spec = SweepSpec(
        axes=(
            (ax.SHEATH_KINETIC, (0.1,)),
            (ax.SHEATH_STATIC_RATIO, (1.5,)),
            (ax.SHEATH_VISCOUS, (12.0,)),
            (ax.TORQUE_CONSTANT_RATIO, (0.85,)),
            (ax.MOTOR_COULOMB, (0.2,)),
            (ax.IMU_LATENCY, (0.02,)),
        )
    )
    suit = spec.points()[0].suit(SuitParameters())
    assert suit.sheath.kinetic_coefficient == 0.1 and suit.sheath.static_to_kinetic_ratio == 1.5
    assert suit.sheath.viscous_coefficient_ns_m == 12.0
    assert suit.motor.torque_constant_ratio == 0.85 and suit.motor.coulomb_friction_nm == 0.2
    assert suit.imu.latency_s == 0.02
    assert ax.plant_values(suit) == {
        ax.SHEATH_KINETIC: 0.1,
        ax.SHEATH_STATIC_RATIO: 1.5,
        ax.SHEATH_VISCOUS: 12.0,
        ax.TORQUE_CONSTANT_RATIO: 0.85,
        ax.MOTOR_COULOMB: 0.2,
        ax.IMU_LATENCY: 0.02,
    }


def test_mapping_round_trip():
    spec = SweepSpec(
        name="round",
        axes=((ax.BLEND_WIDTH, (0.5, 2.0)), (ax.BLEND_CENTER, (0.0,))),
        participants=3,
        seeds=(1, 2),
        conditions=("support_25",),
        speeds=("V2",),
        identification="nominal",
        bench="quick",
    )
    assert SweepSpec.from_mapping(spec.to_dict()) == spec


def test_toml_example_of_the_docstring(tmp_path: Path):
    doc = spec_module.__doc__
    assert doc is not None
    example = doc.split("TOML (``bowden sweep --spec FILE``)::")[1]
    lines = [line[4:] for line in example.splitlines() if line.startswith("    ") or not line.strip()]
    file = tmp_path / "friction.toml"
    file.write_text("\n".join(lines))
    spec = SweepSpec.from_toml(file)
    assert spec.name == "friction" and spec.identification == "per-suit"
    assert spec.conditions == ("pretension", "support_25", "support_50")
    assert dict(spec.axes) == {
        ax.SHEATH_KINETIC: (0.1, 0.14, 0.18),
        ax.TORQUE_CONSTANT_RATIO: (0.85, 1.0, 1.15),
    }
    assert len(spec.points()) == 9


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"axes": (("friction", (0.1,)),)}, "unknown sweep axis 'friction'"),
        ({"axes": ((ax.BLEND_WIDTH, (-0.5,)),)}, "blend_width_rad_s = -0.5 must be positive"),
        ({"axes": ((ax.BLEND_WIDTH, (0.0,)),)}, "blend_width_rad_s = 0.0 must be positive"),
        (
            {"axes": ((ax.BLEND_01, (1.0,)), (ax.BLEND_99, (0.5,)))},
            "blend_velocity_01_rad_s < blend_velocity_99",
        ),
        ({"axes": ((ax.BLEND_01, (1.5,)),)}, "no point of the sweep"),
        ({"axes": ((ax.BLEND_01, (-1.0,)), (ax.BLEND_WIDTH, (1.0,)))}, "both set the blend"),
        ({"axes": ((ax.BLEND_99, ()),)}, "sweep axis blend_velocity_99_rad_s has no values"),
        ({"axes": ((ax.BLEND_99, (1.0, 1.0)),)}, "lists a value twice"),
        ({"axes": ((ax.BLEND_99, (math.nan,)),)}, "is not a finite number"),
        ({"axes": ((ax.BLEND_99, (True,)),)}, "is not a finite number"),
        ({"axes": ((ax.BLEND_99, (50.0,)),)}, "within ±20"),
        ({"axes": ((ax.BLEND_99, (1.0,)), (ax.BLEND_99, (2.0,)))}, "given twice"),
        ({"axes": ((ax.TORQUE_CONSTANT_RATIO, (2.0,)),)}, "torque_constant_ratio = 2.0"),
        ({"axes": ((ax.SHEATH_KINETIC, (-0.1,)),)}, "kinetic_coefficient"),
        ({"participants": 1}, "participants must be an integer in [2, 500]"),
        ({"repetitions": 1}, "repetitions must be an integer in [2, 100]"),
        ({"seeds": ()}, "seeds must list at least one seed"),
        ({"seeds": (0, 0)}, "seeds lists a seed twice"),
        ({"seeds": (-1,)}, "seeds must be an integer"),
        ({"conditions": ("no_suit",)}, "conditions: unknown value 'no_suit'"),
        ({"speeds": ("V4",)}, "speeds: unknown value 'V4'"),
        ({"identification": "never"}, "identification must be one of per-suit, nominal"),
        ({"bench": "long"}, "bench must be one of paper, quick"),
        ({"name": " "}, "name must be a non-empty string"),
    ],
)
def test_bad_specs_are_refused_naming_the_field(kwargs, message):
    with pytest.raises(ParameterError) as info:
        SweepSpec(**kwargs)
    assert message in str(info.value)


def test_plant_error_names_the_axis_and_the_simulator_field():
    with pytest.raises(ParameterError) as info:
        SweepSpec(axes=((ax.IMU_LATENCY, (0.05, 0.5)),))
    assert "sweep axis imu_latency_s = 0.5" in str(info.value)
    assert "ImuParameters.latency_s" in str(info.value)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("participants = 3\ncolour = 'red'\n", "unknown key 'colour'"),
        ("axes = 3\n", "'axes' must be a table"),
        ("[axes]\nblend_velocity_99_rad_s = ['fast']\n", "'fast' is not a number"),
        ("support = [0.75]\n", "support 0.75 is not a condition"),
        ("participants = \n", "is not valid TOML"),
        ("participants = 1.5\n", "participants must be an integer"),
    ],
)
def test_bad_toml_files_are_refused(tmp_path: Path, text, message):
    file = tmp_path / "spec.toml"
    file.write_text(text)
    with pytest.raises(ParameterError) as info:
        SweepSpec.from_toml(file)
    assert message in str(info.value)


def test_missing_spec_file(tmp_path: Path):
    with pytest.raises(ParameterError, match="cannot read the sweep spec"):
        SweepSpec.from_toml(tmp_path / "absent.toml")


def test_support_levels_map_to_conditions():
    levels = spec_module.parse_support(["pretension", 0.25, "0.5"])
    assert levels == ("pretension", "support_25", "support_50")
    assert spec_module.parse_support(["support_25"]) == ("support_25",)
    with pytest.raises(ParameterError, match="support 'no_suit'"):
        spec_module.parse_support(["no_suit"])


def test_command_line_values():
    assert spec_module.parse_values("x", "-1, -0.5,0") == (-1.0, -0.5, 0.0)
    with pytest.raises(ParameterError, match="sweep axis x: '1,a' is not a comma-separated list"):
        spec_module.parse_values("x", "1,a")


def test_with_axis_replaces_or_appends():
    spec = preset("blend-velocity").with_axis(ax.BLEND_99, (0.5,))
    assert dict(spec.axes)[ax.BLEND_99] == (0.5,)
    assert spec.axis_names == (ax.BLEND_01, ax.BLEND_99)
    more = spec.with_axis(ax.TORQUE_CONSTANT_RATIO, (0.9, 1.1))
    assert more.axis_names[-1] == ax.TORQUE_CONSTANT_RATIO
    with pytest.raises(ParameterError, match="unknown sweep axis"):
        spec.with_axis("speed", (1.0,))
    with pytest.raises(ParameterError, match="unknown sweep preset 'fast'"):
        preset("fast")


def test_a_spec_file_that_is_not_utf8_is_a_clear_error(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_bytes(b"\xff\xfe name = 'x'")
    with pytest.raises(ParameterError, match="not UTF-8 text"):
        SweepSpec.from_toml(spec)
