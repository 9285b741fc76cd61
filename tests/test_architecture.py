"""Meta-tests: the dependency rules of docs/design.md and the controller contract hold."""

import ast
import math
from pathlib import Path

import pytest

import bowden
from bowden.model.model_file import save_model

PACKAGE = Path(bowden.__file__).parent
PURE = ("model", "control", "analysis", "stats")
FORBIDDEN = ("hardware", "runtime", "sim", "web", "study", "cli")


def imported_modules(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


@pytest.mark.parametrize("layer", PURE)
def test_pure_layers_never_import_the_outer_layers(layer):
    folder = PACKAGE / layer
    if not folder.exists():
        pytest.skip(f"bowden.{layer} does not exist yet")
    offenders = []
    for path in sorted(folder.rglob("*.py")):
        for module in imported_modules(path):
            parts = module.split(".")
            if parts[0] == "bowden" and len(parts) > 1 and parts[1] in FORBIDDEN:
                offenders.append(f"{path.relative_to(PACKAGE)} imports {module}")
    assert not offenders, "\n".join(offenders)


def test_controller_contract_of_design_md(tmp_path):
    # The controller contract of docs/design.md, run as written.
    from bowden.control import build_controller
    from bowden.model import CompensationModel, Subject

    save_model(CompensationModel.from_friction(k=0.1), tmp_path / "model.json")
    ctrl = build_controller(
        model=str(tmp_path / "model.json"),
        support=0.5,
        subject=Subject(height_m=1.70, mass_kg=63.0, sex="female"),
        hand_load_kg=0.5,
    )
    cmd = ctrl.step(0.0, math.radians(60.0), 0.5, motor_velocity_rad_s=math.nan, motor_torque_nm=math.nan)
    assert isinstance(cmd.torque_nm, float) and isinstance(cmd.tension_n, float)
    assert cmd.torque_nm > 0.0 and cmd.tension_n > 10.0
    pre = build_controller(
        model=tmp_path / "model.json",
        support="pretension",
        subject=Subject(height_m=1.70, mass_kg=63.0, sex="female"),
    )
    assert pre.step(0.0, 1.0, 0.0).tension_n == 10.0


def test_every_error_subclasses_a_builtin():
    from bowden import errors

    for name in dir(errors):
        obj = getattr(errors, name)
        if isinstance(obj, type) and issubclass(obj, errors.BowdenError) and obj is not errors.BowdenError:
            generic = (object, Exception, BaseException)
            builtin_bases = [b for b in obj.__mro__ if b.__module__ == "builtins" and b not in generic]
            assert builtin_bases, f"{name} should subclass a builtin exception"
