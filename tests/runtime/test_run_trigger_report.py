"""`bowden run --trigger command:...` says how long each edge took to send and warns when a command's
latency exceeds what `bowden emg import` accepts (issue 27, item 3)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from bowden.analysis.emg.sync import RESIDUAL_TOLERANCE_S
from bowden.cli import main
from bowden.cli.run import _trigger_report
from bowden.runtime.sync_events import SYNC_KIND, SyncEvent
from bowden.store.study_store import StudyStore

LOGGER = Path(__file__).parent / "trigger_log.py"


def test_a_command_trigger_reports_its_edges_and_warns_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    store, levels = tmp_path / "study.db", tmp_path / "levels.txt"
    # A Python program as the trigger: its start-up alone takes tens of milliseconds.
    trigger = f"command:{sys.executable} {LOGGER} {levels} {{level}}"
    code = main(["run", "--backend", "sim", "--duration", "1", "--speed", "V3", "--condition", "support_50",
                 "--record", str(store), "--trigger", trigger])
    assert code == 0
    out = capsys.readouterr().out
    with StudyStore(store) as opened:
        events = opened.read_sql("SELECT time_s, message FROM events WHERE kind = ?", (SYNC_KIND,))
    sync = {e.edge: e for e in (SyncEvent.from_event(t, m) for t, m in events.itertuples(index=False))}
    report = [line for line in out.splitlines() if line.startswith("sync: ")]
    assert report[0] == (
        f"sync: trigger edges sent: start within {1e3 * sync['start'].uncertainty_s:.3f} ms, "
        f"end within {1e3 * sync['end'].uncertainty_s:.3f} ms"
    )
    assert max(e.uncertainty_s for e in sync.values()) > RESIDUAL_TOLERANCE_S  # a program is slow
    assert len(report) == 2 and report[1].startswith("sync: warning: a trigger edge took ")
    assert "--trigger gpio:CHIP:LINE" in report[1] and "2 ms residual bowden emg import accepts" in report[1]


def test_fast_edges_get_no_warning() -> None:
    lines = _trigger_report({"start": 4e-6, "end": 5e-6})
    assert lines == ["sync: trigger edges sent: start within 0.004 ms, end within 0.005 ms"]
    assert _trigger_report({}) == []
