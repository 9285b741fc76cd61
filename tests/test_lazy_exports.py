"""The packages that export lazily (PEP 562) give every exported name as it was exported.

A lazy export named like a submodule of its package is shadowed by that module as soon as anything
imports the submodule (the import system sets the package's attribute), so ``from bowden.analysis
import sparc`` gave the module instead of the function, depending on what ran first.
"""

import ast
import importlib
import pkgutil
import subprocess
import sys
import types
from pathlib import Path

import pytest

import bowden

LAZY_PACKAGES = (
    "bowden.analysis", "bowden.analysis.emg", "bowden.identify", "bowden.runtime", "bowden.sweep",
    "bowden.sim",
)


@pytest.mark.parametrize("name", LAZY_PACKAGES)
def test_no_lazy_export_is_named_like_a_submodule(name: str) -> None:
    package = importlib.import_module(name)
    submodules = {info.name for info in pkgutil.iter_modules(package.__path__)}
    assert not submodules & set(package._EXPORTS)


@pytest.mark.parametrize("name", LAZY_PACKAGES)
def test_every_export_is_what_it_names_after_every_submodule_is_imported(name: str) -> None:
    package = importlib.import_module(name)
    for info in pkgutil.iter_modules(package.__path__):
        importlib.import_module(f"{name}.{info.name}")
    for export in package.__all__:
        value = getattr(package, export)
        assert not isinstance(value, types.ModuleType), export


@pytest.mark.parametrize("name", LAZY_PACKAGES)
def test_dir_lists_every_export_before_any_is_imported(name: str) -> None:
    # In a fresh interpreter, where nothing has imported the exports yet (dir() feeds completion).
    probe = f"import {name} as p; print(sorted(set(p.__all__) - set(dir(p))))"
    result = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=True
    )
    assert result.stdout.strip() == "[]"


@pytest.mark.parametrize("name", LAZY_PACKAGES)
def test_an_unknown_name_is_an_attribute_error_naming_the_package(name: str) -> None:
    package = importlib.import_module(name)
    with pytest.raises(AttributeError, match=rf"module '{name}' has no attribute 'no_such_name'"):
        package.no_such_name  # noqa: B018
    assert not hasattr(package, "no_such_name")


def test_the_lazy_getattr_is_written_once() -> None:
    # Every package takes its __getattr__ from bowden/_lazy.py instead of copying it.
    root = Path(bowden.__file__).parent
    copies = [
        str(path.relative_to(root))
        for path in sorted(root.rglob("__init__.py"))
        if any(isinstance(node, ast.FunctionDef) and node.name in ("__getattr__", "__dir__")
               for node in ast.parse(path.read_text(encoding="utf-8")).body)
    ]
    assert copies == []
