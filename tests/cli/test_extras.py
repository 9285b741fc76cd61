"""A command whose extra is missing is marked in ``bowden --help`` and refused in one line."""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from bowden.cli import PROVIDERS, missing_dependency_error

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


def test_a_dependency_missing_deep_inside_a_command_is_one_line(tmp_path: Path) -> None:
    # python-can is a core dependency now; should it be missing all the same, the simulated suit's
    # import of it deep inside ``bowden run`` is one line naming it, not a traceback.
    refused = subprocess.run(
        [sys.executable, "-c", WITHOUT.format(names=["can"], argv=["run", "--backend", "sim",
                                                                   "--duration", "1"])],
        capture_output=True, text=True, timeout=300, check=False, cwd=tmp_path,
    )
    assert refused.returncode == 1
    assert refused.stderr.strip().splitlines()[-1] == (
        "bowden: error: bowden run needs python-can, a core dependency of bowden (can missing): "
        "pip install python-can (or reinstall bowden)"
    )
    assert "Traceback" not in refused.stderr


def test_a_module_that_is_no_dependency_is_still_a_traceback() -> None:
    error = ModuleNotFoundError("No module named 'bowden.nothing'", name="bowden.nothing")
    assert missing_dependency_error("bowden run", error) is None
    extra = missing_dependency_error("bowden analyze", ModuleNotFoundError(name="edfio.io"))
    assert str(extra) == "bowden analyze needs the emg extra (edfio missing): pip install 'bowden[emg]'"


def test_providers_match_pyproject_and_the_commands_extras() -> None:
    pyproject = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())["project"]

    def names(requirements: list[str]) -> set[str]:
        return {re.split(r"[\[<>=!~ ;]", r, maxsplit=1)[0].lower() for r in requirements}

    extras = {extra: names(reqs) for extra, reqs in pyproject["optional-dependencies"].items()}
    extras["cluster"] |= {"distributed"}  # dask[distributed]
    for module, (distribution, extra) in PROVIDERS.items():
        wanted = names(pyproject["dependencies"]) if extra is None else extras[extra]
        assert distribution in wanted, (module, extra)
    for command in ("serve", "sweep"):
        extra, modules = importlib.import_module(f"bowden.cli.{command}").EXTRA
        assert all(PROVIDERS[module][1] == extra for module in modules), command
