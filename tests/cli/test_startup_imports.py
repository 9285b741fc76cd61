"""The command line starts without the heavy libraries: each imports inside the command that uses it.

``bowden --help`` and every ``bowden <command> --help`` (and so every ``bowden run`` a real-time test
or a user starts) should not pay seconds of start-up for pandas, SciPy's linear algebra, statistics and
signal processing, statsmodels, matplotlib, numba or MuJoCo. Each check runs in a fresh interpreter, where
``sys.modules`` shows what the start-up imported.
"""

import json
import subprocess
import sys

import pytest

from bowden.cli import command_names

HEAVY = ("pandas", "scipy.linalg", "scipy.stats", "scipy.signal", "statsmodels", "matplotlib", "numba",
         "mujoco")

# Runs ``python -m bowden ARGS`` in this interpreter, then prints the heavy modules it imported.
_PROBE = """
import json, runpy, sys
heavy = json.loads(sys.argv[1])
sys.argv = ["bowden", *sys.argv[2:]]
try:
    runpy.run_module("bowden", run_name="__main__", alter_sys=True)
except SystemExit:
    pass
sys.stdout.flush()
sys.stderr.write("HEAVY " + json.dumps(sorted(m for m in heavy if m in sys.modules)) + "\\n")
"""

_BUILD_PARSER = """
import json, sys
from bowden.cli import build_parser
build_parser()
print(json.dumps(sorted(m for m in json.loads(sys.argv[1]) if m in sys.modules)))
"""

_IMPORT_IDENTIFY = """
import json, sys
import bowden.cli.identify
print(json.dumps(sorted(m for m in json.loads(sys.argv[1]) if m in sys.modules)))
"""


def _heavy_imported_by(*args: str) -> list[str]:
    result = subprocess.run(
        [sys.executable, "-c", _PROBE, json.dumps(HEAVY), *args],
        capture_output=True, text=True, timeout=120, check=True,
    )
    assert "usage: bowden" in result.stdout, result.stderr
    line = result.stderr.strip().splitlines()[-1]
    assert line.startswith("HEAVY "), result.stderr
    heavy: list[str] = json.loads(line.removeprefix("HEAVY "))
    return heavy


@pytest.mark.parametrize("command", command_names())
def test_a_commands_help_imports_no_heavy_library(command):
    assert _heavy_imported_by(command, "--help") == []


def _heavy_imported_running(script: str) -> list[str]:
    """The heavy libraries a fresh interpreter has imported after ``script`` (which prints them)."""
    result = subprocess.run([sys.executable, "-c", script, json.dumps(HEAVY)],
                            capture_output=True, text=True, timeout=120, check=True)
    return list(json.loads(result.stdout))


def test_importing_the_identify_command_imports_no_heavy_library():
    # cli/identify.py reads bowden.identify.settings at parse time; the fitting and the figures are
    # imported when it runs.
    assert _heavy_imported_running(_IMPORT_IDENTIFY) == []


def test_bowden_help_imports_no_heavy_library():
    # The whole parser imports every command's module.
    assert _heavy_imported_by("--help") == []


def test_building_the_parser_imports_no_heavy_library():
    assert _heavy_imported_running(_BUILD_PARSER) == []


def test_a_command_imports_only_its_own_module():
    # bowden run ... builds a parser with the run command alone: no other command's module is imported.
    probe = (
        "import sys; from bowden.cli import main\n"
        "try:\n    main(['version'])\nexcept SystemExit:\n    pass\n"
        "print(sorted(m for m in sys.modules\n"
        "             if m.startswith('bowden.cli.') and not m.startswith('bowden.cli._')))"
    )
    result = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=True
    )
    assert result.stdout.strip().splitlines()[-1] == "['bowden.cli.version']"
