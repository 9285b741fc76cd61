"""`bowden study --workers N` / `--scheduler ADDRESS`: refused in one line when they cannot run."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from bowden.cli import main

# ``sys.modules[name] = None`` makes a module unimportable, as if the cluster extra were not installed.
WITHOUT_DASK = (
    "import sys\nfor name in ('dask', 'distributed'): sys.modules[name] = None\n"
    "from bowden.cli import main\nsys.exit(main({argv!r}))\n"
)


def test_workers_and_scheduler_are_mutually_exclusive(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["study", "--workers", "2", "--scheduler", "tcp://127.0.0.1:8786", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err


def test_a_bad_scheduler_address_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("distributed")
    assert main(["study", "--scheduler", "nonsense", "--quiet", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "cannot reach the Dask scheduler at nonsense" in err and "Traceback" not in err


def test_zero_workers_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["study", "--workers", "0", "--quiet", "--out", str(tmp_path)]) == 1
    assert "workers must be an integer in [1, 1024], got 0" in capsys.readouterr().err


def test_a_scheduler_without_dask_names_the_extra(tmp_path: Path) -> None:
    argv = ["study", "--scheduler", "tcp://127.0.0.1:8786", "--quiet", "--out", str(tmp_path / "s")]
    refused = subprocess.run(
        [sys.executable, "-c", WITHOUT_DASK.format(argv=argv)],
        capture_output=True, text=True, timeout=120, check=False,
    )
    assert refused.returncode == 1, refused.stderr
    lines = refused.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in refused.stderr
    assert "bowden study --scheduler runs on Dask" in lines[0]
    assert "pip install 'bowden[cluster]'" in lines[0] and "'cluster' extra" in lines[0]
