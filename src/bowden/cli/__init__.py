"""The ``bowden`` command.

Each subcommand lives in its own module of this package and exposes ``register(subparsers)``, which
adds its parser and sets ``handler`` to a function taking the parsed namespace and returning an
exit code. Modules are discovered, so a new subcommand is one new file and no edit here. A module that
needs an optional extra says so with ``EXTRA = (extra, (module, ...))``: ``bowden --help`` then marks
the command when the extra is missing, and running it is one line naming the extra to install.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import pkgutil
import sys
from collections.abc import Sequence

from bowden import __version__
from bowden.errors import BowdenError, MissingExtraError


def build_parser() -> argparse.ArgumentParser:
    """Build the top-level parser with every subcommand module of this package registered."""
    parser = argparse.ArgumentParser(
        prog="bowden",
        description="Sensorless tension control of cable-driven exosuits.",
    )
    parser.add_argument("--version", action="version", version=f"bowden {__version__}")
    subparsers = parser.add_subparsers(title="commands", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        module.register(subparsers)
        extra = getattr(module, "EXTRA", None)
        if extra is not None:
            _guard_extra(subparsers, info.name, *extra)
    return parser


def missing_modules(modules: Sequence[str]) -> list[str]:
    """The modules of ``modules`` that cannot be imported here."""
    return [name for name in modules if importlib.util.find_spec(name) is None]


def _guard_extra(subparsers: argparse._SubParsersAction[argparse.ArgumentParser], command: str,
                 extra: str, modules: Sequence[str]) -> None:
    """Mark ``command`` in ``bowden --help`` and make running it one line, when ``extra`` is missing."""
    missing = missing_modules(modules)
    if not missing:
        return
    install = f"pip install 'bowden[{extra}]'"
    for action in subparsers._choices_actions:
        if action.dest == command:
            action.help = f"{action.help} [needs: {install}]"
    message = f"bowden {command} needs the {extra} extra ({', '.join(missing)} missing): {install}"

    def refuse(args: argparse.Namespace) -> int:
        raise MissingExtraError(message)

    subparsers.choices[command].set_defaults(handler=refuse)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the process exit code (tests call this directly)."""
    try:
        parser = build_parser()  # imports every subcommand: a Ctrl-C can land here too
        args = parser.parse_args(argv)
        handler = getattr(args, "handler", None)
        if handler is None:
            parser.print_help()
            return 2
        code: int = handler(args)
        sys.stdout.flush()  # a closed pipe shows here, where it is handled, not at interpreter exit
    except BowdenError as error:
        print(f"bowden: error: {error}", file=sys.stderr)
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
