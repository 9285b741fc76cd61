"""Package exports imported on first use (PEP 562), written once for every package that needs them.

A package whose public face names heavy modules (pandas, SciPy, numba, statsmodels, MuJoCo) would
make every light submodule pay for them: importing ``bowden.sim.link`` or ``bowden.identify.settings``
first imports the package's ``__init__``. Such a package lists its exports in a ``{name: module}``
table and takes its module-level ``__getattr__`` and ``__dir__`` from :func:`lazy_exports`; its
``__all__`` stays explicit and its ``TYPE_CHECKING`` imports give type checkers the names.

An export must not share its name with a submodule of its package: importing that submodule sets the
package's attribute to the module, which then shadows the lazy export (``tests/test_lazy_exports.py``).
Such a name is imported eagerly instead.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any


def lazy_exports(
    package: str, exports: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of a package that imports its exports on first use.

    Parameters
    ----------
    package
        The package's ``__name__``; it must be in ``sys.modules`` already (true while its
        ``__init__`` runs).
    exports
        Each lazily exported name and the module that defines it.

    Returns
    -------
    tuple
        ``(__getattr__, __dir__)``, to be bound at the package's top level. ``__getattr__`` imports
        the defining module, caches the value in the package's namespace (so the next access costs
        nothing) and raises ``AttributeError`` for a name the table does not hold.
    """
    namespace = vars(sys.modules[package])

    def __getattr__(name: str) -> Any:
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(exports))

    return __getattr__, __dir__
