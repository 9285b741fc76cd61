"""``bowden version``: print the installed version and the versions of key dependencies."""

from __future__ import annotations

import argparse
import platform
from importlib import metadata

from bowden import __version__

_DEPENDENCIES = ("numpy", "scipy", "pandas", "statsmodels", "python-can", "python-osc")


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser("version", help="print the bowden version and its environment")
    parser.add_argument("--verbose", "-v", action="store_true", help="also list dependency versions")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    print(f"bowden {__version__}")
    if args.verbose:
        print(f"python {platform.python_version()}")
        for name in _DEPENDENCIES:
            try:
                print(f"{name} {metadata.version(name)}")
            except metadata.PackageNotFoundError:
                print(f"{name} (not installed)")
    return 0
