import importlib
import subprocess
import sys

import pytest

from bowden import __version__
from bowden.cli import build_parser, main


def test_version_command(capsys):
    assert main(["version"]) == 0
    assert capsys.readouterr().out.strip() == f"bowden {__version__}"


def test_version_verbose_lists_dependencies(capsys):
    assert main(["version", "--verbose"]) == 0
    out = capsys.readouterr().out
    assert "numpy" in out and "python" in out


def test_help_lists_every_discovered_subcommand(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    choices = build_parser()._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    assert "version" in choices
    for name in choices:
        assert name in out


def test_no_command_prints_help_and_fails(capsys):
    assert main([]) == 2
    assert "usage: bowden" in capsys.readouterr().out


def test_unknown_command_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["no-such-command"])
    assert exit_info.value.code == 2


def test_module_entry_point_runs():
    result = subprocess.run(
        [sys.executable, "-m", "bowden", "version"], capture_output=True, text=True, check=True
    )
    assert result.stdout.strip() == f"bowden {__version__}"


def test_every_subcommand_help_renders_cleanly(capsys):
    # argparse %-formats argument help but not descriptions: a literal "%%" there shows up doubled.
    choices = build_parser()._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    for name in choices:
        with pytest.raises(SystemExit) as exit_info:
            main([name, "--help"])
        assert exit_info.value.code == 0
        out = capsys.readouterr().out
        assert f"usage: bowden {name}" in out
        assert "%%" not in out and "%(" not in out, name


def test_a_reader_that_goes_away_is_not_a_traceback():
    # ``bowden version -v | head -1``: the pipe closes after the first line.
    process = subprocess.Popen(
        [sys.executable, "-m", "bowden", "version", "--verbose"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )
    assert process.stdout is not None and process.stderr is not None
    process.stdout.read(1)
    process.stdout.close()
    err = process.stderr.read().decode()
    process.wait(timeout=60)
    assert "Traceback" not in err and "BrokenPipeError" not in err


def test_ctrl_c_while_the_subcommands_load_is_one_line(monkeypatch, capsys):
    # A Ctrl-C lands wherever the interpreter is; while the subcommands (and scipy, numba, ...) are
    # imported, that is inside build_parser. Deliver it there, deterministically.
    def interrupted(name, package=None):
        raise KeyboardInterrupt

    monkeypatch.setattr(importlib, "import_module", interrupted)
    assert main(["version"]) == 130
    assert capsys.readouterr().err == "bowden: interrupted\n"


def test_a_value_in_scientific_notation_may_be_negative(tmp_path, capsys):
    # Python 3.11's argparse took "-1e-6" for an unknown option ("expected one argument"); now the
    # option's own check answers.
    args = ["emg", "import", str(tmp_path), "x.csv", "--csv-volts-per-unit"]
    assert build_parser().parse_args([*args, "1e-6"]).csv_volts_per_unit == 1e-6
    assert build_parser().parse_args([*args, "-1e-6"]).csv_volts_per_unit == -1e-6
    assert main([*args, "-1e-6"]) == 1
    assert "--csv-volts-per-unit must be positive, got -1e-06" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # an option that does not exist is still one
        build_parser().parse_args([*args, "1e-6", "-x"])
    assert "unrecognized arguments: -x" in capsys.readouterr().err
