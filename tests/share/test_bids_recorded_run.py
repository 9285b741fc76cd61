"""A store recorded by ``bowden run --backend sim`` (no sEMG, a free participant) exports as valid BIDS."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pandas as pd

from bowden.cli import main
from bowden.contracts import TRIAL_TENSION
from bowden.model import CompensationModel
from bowden.model.model_file import save_model
from bowden.store.study_store import StudyStore

from .conftest import Validate


def test_a_recorded_run_exports_with_zero_validator_errors(tmp_path: Path, bids_errors: Validate) -> None:
    model, store, bids = tmp_path / "model.json", tmp_path / "study.db", tmp_path / "bids"
    save_model(CompensationModel.from_friction(k=0.12), model)
    assert main(["run", "--backend", "sim", "--model", str(model), "--condition", "support_25",
                 "--duration", "0.4", "--rate", "250", "--record", str(store), "--participant", "P07",
                 "--speed", "V2", "--lead-in", "0"]) == 0
    assert main(["export", "--bids", str(bids), str(store)]) == 0
    assert bids_errors(bids) == []
    assert not list(bids.glob("sub-P07/emg/*"))  # no sEMG recorded: none invented
    (physio,) = bids.glob("sub-P07/beh/*_physio.tsv.gz")
    sidecar = json.loads(physio.with_name(physio.name.replace(".tsv.gz", ".json")).read_text())
    with StudyStore(store) as opened:
        samples = opened.trial_samples(1)
        assert sidecar["CompensationModel"]["model_sha256"] == opened.trial_metadata(1)["model_sha256"]
    with gzip.open(physio, "rt") as text:
        back = pd.read_csv(text, sep="\t", header=None, names=sidecar["Columns"], dtype=str)
    tension = np.array([np.nan if v == "n/a" else float(v) for v in back[TRIAL_TENSION]])
    np.testing.assert_array_equal(tension, samples[TRIAL_TENSION].to_numpy())
    events = pd.read_csv(next(bids.glob("sub-P07/beh/*_events.tsv")), sep="\t")
    assert "safe_stop" in set(events["trial_type"])  # the loop's own event, with its message
