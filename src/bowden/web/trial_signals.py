"""The sync signals of the server's trials: the trigger line and LSL (``bowden serve --trigger/--lsl``).

The server knows them only through :class:`TrialSyncs` (``bowden.cli.serve.ConsoleSync`` implements
it on the outputs the command opened): one :class:`~bowden.runtime.trial_sync.TrialSync` per trial,
a sink of its loop, and :func:`end_sync` after the loop, before the trial's recorder closes.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Protocol

from bowden.runtime import LoopReport, Recorder
from bowden.runtime.trial_sync import TrialSync
from bowden.web.trial_setup import TrialSetup

_log = logging.getLogger(__name__)


class TrialSyncs(Protocol):
    """Sync signals for each trial the server runs.

    ``start`` is called once the trial's recorder has started (from a worker thread; it may wait for
    an LSL recorder to connect) and returns the trial's :class:`TrialSync`, whose ``row`` becomes one of
    the loop's sinks; ``ended`` is called after its ``finish`` and says what to tell the operator.
    """

    def start(self, setup: TrialSetup, recorder: Recorder, metadata: Mapping[str, object]) -> TrialSync: ...

    def ended(self, sync: TrialSync) -> list[str]: ...


def end_sync(
    syncs: TrialSyncs,
    sync: TrialSync,
    report: LoopReport | None,
    *,
    error: str | None,
    last_time_s: float,
) -> list[str]:
    """Lower the line, send the last markers and record the sync events; what to tell the operator.

    ``last_time_s`` (the last row the server saw) stands for the stop when the loop failed
    (``report`` None). Never raises: the trial's recording must still be closed after it.
    """
    if report is not None:
        stop_s, reason, clean = report.stop_time_s, report.reason, report.clean
    else:
        stop_s, reason, clean = last_time_s, f"error: {error}", False
    try:
        sync.finish(stop_time_s=stop_s, reason=reason, clean=clean)
        return syncs.ended(sync)
    except Exception as exc:
        _log.exception("ending the trial's sync signals failed")
        return [f"sync: ending the trial's sync signals failed ({exc})"]
