"""The packages that export lazily (PEP 562) give every exported name as it was exported.

A lazy export named like a submodule of its package is shadowed by that module as soon as anything
imports the submodule (the import system sets the package's attribute), so ``from bowden.analysis
import sparc`` gave the module instead of the function, depending on what ran first.
"""

import importlib
import pkgutil
import types

import pytest

LAZY_PACKAGES = ("bowden.analysis", "bowden.analysis.emg", "bowden.runtime", "bowden.sweep", "bowden.sim")


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
