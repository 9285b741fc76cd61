"""The report's list of the trials analysed: how each one stopped and which compensation it ran with.

Trials that stopped for the same reason with the same compensation and model are one row, so a study
of two hundred alike trials is a line or two and a trial that stopped on a fault stands out with its
participant, condition and speed. The model is named by the first digits of the SHA-256 its trials
recorded (:mod:`bowden.model.model_record`); the store's metadata holds the whole hash and the
coefficients.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any, Final

import pandas as pd

from bowden.model.model_record import MODEL_SHA256_KEY

TRIAL_LIST_COLUMNS: Final = ("stop reason", "compensation", "model (SHA-256)", "trials", "which")
# The hex digits of a model's SHA-256 shown (48 bits: two models of one study never share them).
_HASH_DIGITS: Final = 12
# Groups this small list each trial by name; larger ones give the ids.
_NAMED_UP_TO: Final = 3


def trial_list(trials: pd.DataFrame) -> pd.DataFrame:
    """The trials grouped by stop reason, compensation and model (:data:`TRIAL_LIST_COLUMNS`), in
    the order of each group's first trial.

    ``trials`` has the ``trials`` table's ``id``, ``participant``, ``condition``, ``speed``,
    ``stop_reason`` and ``metadata`` (JSON text) of the trials analysed.
    """
    if trials.empty:
        return pd.DataFrame(columns=list(TRIAL_LIST_COLUMNS))
    names = zip(trials["id"], trials["participant"], trials["condition"], trials["speed"], strict=True)
    described = pd.DataFrame({
        "id": trials["id"].astype(int),
        "label": [f"#{i} {p} {c} {s}" for i, p, c, s in names],
        "stop reason": [r if isinstance(r, str) and r else "not recorded" for r in trials["stop_reason"]],
    })
    metadata = [_metadata(text) for text in trials["metadata"]]
    described["compensation"] = [_compensation(m) for m in metadata]
    described["model (SHA-256)"] = [_model(m) for m in metadata]
    keys = ["stop reason", "compensation", "model (SHA-256)"]
    rows = []
    for key, group in described.groupby(keys, sort=False):
        which = ("; ".join(group["label"]) if len(group) <= _NAMED_UP_TO
                 else id_ranges(group["id"].tolist()))
        rows.append((*key, len(group), which))
    return pd.DataFrame(rows, columns=list(TRIAL_LIST_COLUMNS))


def id_ranges(ids: list[int]) -> str:
    """Trial ids as runs: ``#1–#12, #15``."""
    ordered = sorted(ids)
    runs: list[list[int]] = []
    for trial_id in ordered:
        if runs and trial_id == runs[-1][-1] + 1:
            runs[-1].append(trial_id)
        else:
            runs.append([trial_id])
    return ", ".join(f"#{run[0]}" if len(run) == 1 else f"#{run[0]}–#{run[-1]}" for run in runs)


def _metadata(text: object) -> Mapping[str, Any]:
    try:
        value = json.loads(str(text))
    except ValueError:
        return {}
    return value if isinstance(value, dict) else {}


def _compensation(metadata: Mapping[str, Any]) -> str:
    if "compensation" not in metadata:
        return "not recorded"
    compensation = metadata["compensation"]
    return "none (no controller)" if compensation is None else str(compensation)


def _model(metadata: Mapping[str, Any]) -> str:
    digest = metadata.get(MODEL_SHA256_KEY)
    name = metadata.get("model")
    shown = f"{digest[:_HASH_DIGITS]}" if isinstance(digest, str) and digest else "not recorded"
    return f"{shown} ({name})" if isinstance(name, str) and name else shown
