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


def _imports_of(room: str, forbidden: tuple[str, ...]) -> list[str]:
    """Each import in ``bowden.<room>`` of a package in ``forbidden``, as "<file> imports <module>"."""
    offenders = []
    for path in sorted((PACKAGE / room).rglob("*.py")):
        for module in imported_modules(path):
            parts = module.split(".")
            if parts[0] == "bowden" and len(parts) > 1 and parts[1] in forbidden:
                offenders.append(f"{path.relative_to(PACKAGE)} imports {module}")
    return offenders


@pytest.mark.parametrize("layer", PURE)
def test_pure_layers_never_import_the_outer_layers(layer):
    folder = PACKAGE / layer
    if not folder.exists():
        pytest.skip(f"bowden.{layer} does not exist yet")
    offenders = _imports_of(layer, FORBIDDEN)
    assert not offenders, "\n".join(offenders)


# The study store sits below everything that reads or writes it (docs/design.md).
STORE_FORBIDDEN = ("runtime", "sim", "web", "study", "sweep", "engine", "identify", "cli")


def test_the_store_never_imports_the_layers_above_it():
    offenders = _imports_of("store", STORE_FORBIDDEN)
    assert not offenders, "\n".join(offenders)


# Identification turns bench recordings into a model; a real bench's recording must not need the
# simulator to be judged (issue 32), nor anything else above the model (docs/design.md).
IDENTIFY_FORBIDDEN = ("hardware", "runtime", "sim", "web", "study", "sweep", "engine", "cli")


def test_identification_never_imports_the_simulator_or_the_layers_above_it():
    offenders = _imports_of("identify", IDENTIFY_FORBIDDEN)
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


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _runtime_imports(path: Path, package: str, known: set[str]) -> set[str]:
    """The bowden modules ``path`` imports when it runs (inside functions too; not for type checking)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    typing_only = {
        id(sub)
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
        for sub in ast.walk(node)
    }

    def resolve(name: str) -> str | None:
        parts = name.split(".")
        while parts and ".".join(parts) not in known:
            parts.pop()
        return ".".join(parts) or None

    found: set[str] = set()
    for node in ast.walk(tree):
        if id(node) in typing_only:
            continue
        if isinstance(node, ast.Import):
            found.update(filter(None, (resolve(alias.name) for alias in node.names)))
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            for alias in node.names:
                target = resolve(f"{base}.{alias.name}") or resolve(base)
                if target:
                    found.add(target)
    return found


def _import_graph() -> dict[str, set[str]]:
    paths = {_module_name(path): path for path in PACKAGE.rglob("*.py")}
    known = set(paths)
    graph = {}
    for name, path in paths.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        graph[name] = _runtime_imports(path, package, known) - {name}
    return graph


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles: list[list[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    circles.append(sorted(component))
    return circles


def test_the_circle_finder_finds_a_circle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert _circles(graph) == [["a", "b", "c"]]


def test_no_import_circles():
    # Imports inside functions count (they still tie the modules together); TYPE_CHECKING ones do not.
    circles = _circles(_import_graph())
    assert not circles, "import circles:\n" + "\n".join(" ↔ ".join(circle) for circle in circles)
