"""The ``bowden`` command.

Each subcommand lives in its own module of this package and exposes ``register(subparsers)``, which
adds its parser and sets ``handler`` to a function taking the parsed namespace and returning an
exit code. Modules are discovered, so a new subcommand is one new file and no edit here. A module that
needs an optional extra says so with ``EXTRA = (extra, (module, ...))``: ``bowden --help`` then marks
the command when the extra is missing, and running it is one line naming the extra to install. A
dependency found missing only while a command runs (imported deep inside it) is one line too, naming
the extra, or the core dependency, that provides it.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import pkgutil
import re
import sys
from collections.abc import Mapping, Sequence
from typing import Final

from bowden import __version__
from bowden.errors import BowdenError, MissingExtraError

# The top-level modules of bowden's optional and pure-Python core dependencies, with the distribution
# and the extra that provides each (None: the core). Keep in step with pyproject.toml.
PROVIDERS: Final[Mapping[str, tuple[str, str | None]]] = {
    "can": ("python-can", None),
    "pythonosc": ("python-osc", None),
    "smbus2": ("smbus2", "hardware"),
    "starlette": ("starlette", "web"),
    "uvicorn": ("uvicorn", "web"),
    "websockets": ("websockets", "web"),
    "dask": ("dask", "cluster"),
    "distributed": ("distributed", "cluster"),
    "edfio": ("edfio", "emg"),
    "pyxdf": ("pyxdf", "emg"),
    "pylsl": ("pylsl", "lsl"),
    "gpiod": ("gpiod", "gpio"),
}


class _Parser(argparse.ArgumentParser):
    """argparse's parser, but a value such as ``-1e-6`` is a negative number, not an unknown option
    (Python 3.11's argparse knows only ``-1`` and ``-1.5``; 3.13 reads it so too). The subcommands'
    parsers are of this class as well (``add_subparsers`` makes its parsers of the parent's class)."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self._negative_number_matcher = re.compile(r"-\.?\d")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """Build the top-level parser with every subcommand module of this package registered.

    Parameters
    ----------
    command
        Register only this subcommand (one of :func:`command_names`): ``bowden run ...`` then imports
        the run command's module alone, not every other command's (a second of start-up each time).
    """
    parser: argparse.ArgumentParser = _Parser(
        prog="bowden",
        description="Sensorless tension control of cable-driven exosuits.",
    )
    parser.add_argument("--version", action="version", version=f"bowden {__version__}")
    subparsers = parser.add_subparsers(title="commands", metavar="COMMAND", dest="bowden_command")
    for name in command_names():
        if command is not None and name != command:
            continue
        module = importlib.import_module(f"{__name__}.{name}")
        module.register(subparsers)
        extra = getattr(module, "EXTRA", None)
        if extra is not None:
            _guard_extra(subparsers, name, *extra)
    return parser


def command_names() -> list[str]:
    """The subcommands: this package's modules not starting with ``_``, sorted (found without importing)."""
    return sorted(info.name for info in pkgutil.iter_modules(__path__) if not info.name.startswith("_"))


def _named_command(argv: Sequence[str]) -> str | None:
    """The subcommand ``argv`` runs, when its first word names one (else None: the whole parser)."""
    return argv[0] if argv and argv[0] in command_names() else None


def missing_modules(modules: Sequence[str]) -> list[str]:
    """The modules of ``modules`` that cannot be imported here."""
    return [name for name in modules if importlib.util.find_spec(name) is None]


def _guard_extra(subparsers: argparse._SubParsersAction[argparse.ArgumentParser], command: str,
                 extra: str, modules: Sequence[str]) -> None:
    """Mark ``command`` in ``bowden --help`` and make running it one line, when ``extra`` is missing."""
    missing = missing_modules(modules)
    if not missing:
        return
    for action in subparsers._choices_actions:
        if action.dest == command:
            action.help = f"{action.help} [needs: {install_hint(extra)}]"
    error = missing_extra_error(f"bowden {command}", extra, missing)

    def refuse(args: argparse.Namespace) -> int:
        raise error

    subparsers.choices[command].set_defaults(handler=refuse)


def install_hint(extra: str) -> str:
    """The command that installs ``extra`` (``pip install 'bowden[web]'``)."""
    return f"pip install 'bowden[{extra}]'"


def missing_extra_error(command: str, extra: str, missing: Sequence[str]) -> MissingExtraError:
    """The one-line refusal of ``command`` (``"bowden serve"``) whose ``extra`` lacks ``missing`` modules."""
    return MissingExtraError(
        f"{command} needs the {extra} extra ({', '.join(missing)} missing): {install_hint(extra)}"
    )


def missing_dependency_error(command: str, error: ModuleNotFoundError) -> MissingExtraError | None:
    """The one-line message for a dependency of :data:`PROVIDERS` found missing while ``command`` ran.

    None when the missing module is not one of bowden's dependencies (a bug, shown as such).
    """
    module = (error.name or "").partition(".")[0]
    if module not in PROVIDERS:
        return None
    distribution, extra = PROVIDERS[module]
    if extra is not None:
        return missing_extra_error(command, extra, [module])
    return MissingExtraError(
        f"{command} needs {distribution}, a core dependency of bowden ({module} missing): "
        f"pip install {distribution} (or reinstall bowden)"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the process exit code (tests call this directly)."""
    command = "bowden"
    try:
        argv = sys.argv[1:] if argv is None else list(argv)
        # Imports the named subcommand (every one for bowden --help): a Ctrl-C can land here too.
        parser = build_parser(_named_command(argv))
        args = parser.parse_args(argv)
        handler = getattr(args, "handler", None)
        if handler is None:
            parser.print_help()
            return 2
        command = f"bowden {args.bowden_command}"
        code: int = handler(args)
        sys.stdout.flush()  # a closed pipe shows here, where it is handled, not at interpreter exit
    except BowdenError as error:
        print(f"bowden: error: {error}", file=sys.stderr)
        return 1
    except ModuleNotFoundError as error:
        # A dependency imported deep inside a command (not caught by its EXTRA declaration).
        missing = missing_dependency_error(command, error)
        if missing is None:
            raise
        print(f"bowden: error: {missing}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("bowden: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (``bowden version -v | head -1``): send the rest of the output nowhere
        # so that the interpreter's own flush at exit does not fail again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
