"""A trial as BIDS events: the trial itself, its repetitions, what the loop logged, and why it stopped.

BIDS ``_events.tsv`` (bids-specification ``src/modality-agnostic-files/events.md``): ``onset`` and
``duration`` in seconds from the first sample of the file the events belong to, then columns of our
own, each described in the ``_events.json`` sidecar (:data:`EVENTS_SIDECAR`).

Rows, in onset order:

- ``trial``: the whole recording, with the trial's condition, speed, support and stop reason;
- ``repetition``: each complete raise-and-lower cycle of the reference the wearer followed
  (:func:`bowden.analysis.segmentation.find_cycles` on ``reference_elevation_rad``), numbered from 1;
  the analysis drops the first of a trial that holds several (adaptation), the export keeps them all;
- one row per event the loop stored (``start``, ``safe_stop``, ``fault``, …) with its message;
- ``stop``: the last sample, with the stop reason.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any, Final

import numpy as np
import pandas as pd

from bowden.analysis.segmentation import find_cycles
from bowden.contracts import TRIAL_REFERENCE_ELEVATION, TRIAL_TIME
from bowden.errors import RecordingError

EVENT_COLUMNS: Final = (
    "onset",
    "duration",
    "trial_type",
    "condition",
    "speed",
    "support",
    "repetition",
    "stop_reason",
    "message",
)

EVENTS_SIDECAR: Final[dict[str, Any]] = {
    "onset": {"Description": "Time from the file's first sample.", "Units": "s"},
    "duration": {"Description": "Length of the event (0: an instant).", "Units": "s"},
    "trial_type": {
        "Description": "What the row marks.",
        "Levels": {
            "trial": "the whole recording of one trial",
            "repetition": "one raise-and-lower cycle of the reference elevation the wearer followed",
            "stop": "the last recorded control cycle",
            "start": "event logged by the control loop",
            "safe_stop": "event logged by the control loop",
            "fault": "event logged by the control loop",
        },
    },
    "condition": {
        "Description": "Experimental condition (no_suit, pretension, support_25, support_50, or a lab's own)."
    },
    "speed": {"Description": "Movement speed of the reference (V1 slowest ... V3, or a lab's own)."},
    "support": {"Description": "Fraction of the arm's gravity moment the suit supports (n/a: none)."},
    "repetition": {
        "Description": "Repetition number within the trial, from 1 (the analysis drops the "
        "first of a trial with several)."
    },
    "stop_reason": {"Description": "Why the control loop stopped the trial."},
    "message": {"Description": "The control loop's message with a logged event."},
}


def events_sidecar(kinds: Iterable[str]) -> dict[str, Any]:
    """:data:`EVENTS_SIDECAR` with a level for every ``trial_type`` of the file: the validator refuses a
    value its ``Levels`` do not list, and the store's events have kinds of their own (an EMG import's
    ``emg_import``, a trigger's ``sync``)."""
    levels = dict(EVENTS_SIDECAR["trial_type"]["Levels"])
    for kind in kinds:
        levels.setdefault(str(kind), f"event bowden stored with the trial (kind {kind}; see message)")
    return {**EVENTS_SIDECAR, "trial_type": {**EVENTS_SIDECAR["trial_type"], "Levels": levels}}


def trial_events(
    samples: pd.DataFrame,
    events: pd.DataFrame,
    *,
    labels: dict[str, Any],
    start_s: float,
) -> pd.DataFrame:
    """The trial's event rows, onsets counted from ``start_s`` (the loop time of the file's first sample).

    ``samples`` are the trial's control cycles, ``events`` its stored events (``time_s``, ``kind``,
    ``message``), ``labels`` its ``condition``, ``speed``, ``support`` and ``stop_reason``.
    """
    time = samples[TRIAL_TIME].to_numpy(dtype=np.float64)
    first, last = (float(time[0]), float(time[-1])) if time.size else (start_s, start_s)
    rows: list[dict[str, Any]] = [
        {"onset": first - start_s, "duration": last - first, "trial_type": "trial", **labels}
    ]
    for cycle in _cycles(samples):
        rows.append(
            {
                "onset": cycle.start_s - start_s,
                "duration": cycle.duration_s,
                "trial_type": "repetition",
                "repetition": cycle.number,
            }
        )
    for time_s, kind, message in events[["time_s", "kind", "message"]].itertuples(index=False, name=None):
        onset = last if time_s is None or not math.isfinite(float(time_s)) else float(time_s)
        rows.append({"onset": onset - start_s, "duration": 0.0, "trial_type": str(kind), "message": message})
    rows.append(
        {
            "onset": last - start_s,
            "duration": 0.0,
            "trial_type": "stop",
            "stop_reason": labels.get("stop_reason"),
        }
    )
    table = pd.DataFrame(rows, columns=list(EVENT_COLUMNS))
    # A file's events may start before it (EMG that started after the loop): BIDS onsets may be negative.
    return table.sort_values("onset", kind="stable").reset_index(drop=True)


def _cycles(samples: pd.DataFrame) -> list[Any]:
    """The reference's complete cycles; none for a free run (no reference) or one that never moved."""
    if TRIAL_REFERENCE_ELEVATION not in samples or len(samples) == 0:
        return []
    reference = samples[TRIAL_REFERENCE_ELEVATION].to_numpy(dtype=np.float64)
    if not np.all(np.isfinite(reference)):
        return []
    try:
        return find_cycles(samples[TRIAL_TIME].to_numpy(dtype=np.float64), reference)
    except RecordingError:
        return []
