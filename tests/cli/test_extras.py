"""A command whose extra is missing is marked in ``bowden --help`` and refused in one line."""

from __future__ import annotations

import subprocess
import sys

import pytest

# ``sys.modules[name] = None`` makes a module unimportable (and invisible to find_spec), as if the
# extra providing it had not been installed.
WITHOUT = "import sys\nfor name in {names!r}: sys.modules[name] = None\nfrom bowden.cli import main\n" \
          "sys.exit(main({argv!r}))\n"


def bowden_without(names: list[str], argv: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", WITHOUT.format(names=names, argv=argv)],
                          capture_output=True, text=True, timeout=120, check=False)


@pytest.mark.parametrize(("command", "extra", "modules"), [
    ("serve", "web", ["starlette"]),
    ("sweep", "cluster", ["dask", "distributed"]),
])
def test_missing_extra_is_marked_and_refused_in_one_line(command: str, extra: str,
                                                         modules: list[str]) -> None:
    listing = bowden_without(modules, ["--help"])
    assert listing.returncode == 0, listing.stderr
    joined = " ".join(listing.stdout.split())
    assert f"[needs: pip install 'bowden[{extra}]']" in joined, listing.stdout
    refused = bowden_without(modules, [command])
    assert refused.returncode == 1
    assert refused.stderr.strip().splitlines() == [
        f"bowden: error: bowden {command} needs the {extra} extra ({', '.join(modules)} missing): "
        f"pip install 'bowden[{extra}]'"
    ]
    assert "Traceback" not in refused.stderr


def test_installed_extras_are_not_marked() -> None:
    listing = bowden_without([], ["--help"])
    assert "[needs:" not in listing.stdout
