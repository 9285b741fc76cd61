"""The report's musculoskeletal posterior deltoid under either compensation (issue 30, item 5)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from bowden import contracts as c
from bowden.model import CompensationLine, CompensationModel
from bowden.sim import ProtocolSettings, generate_cohort, simulate_trial
from bowden.sim.results import phase_masks
from bowden.study.compensation.posterior_deltoid import (
    COLUMN,
    musculoskeletal_posterior_deltoid,
    posterior_deltoid_paragraph,
)

MODEL = CompensationModel(
    raising=CompensationLine(intercept_nm=0.11, slope_m=0.02),
    lowering=CompensationLine(intercept_nm=-0.11, slope_m=0.012),
)


def test_the_paragraph_compares_the_compensations_at_fifty_percent() -> None:
    fifty, pre = c.CONDITION_LABELS[c.CONDITION_SUPPORT_50], c.CONDITION_LABELS[c.CONDITION_PRETENSION]
    index = pd.MultiIndex.from_tuples(
        [(pre, "V1", "paper"), (pre, "V1", "dynamic"), (fifty, "V1", "paper"), (fifty, "V1", "dynamic"),
         (fifty, "V3", "paper"), (fifty, "V3", "dynamic")],
        names=["condition", "speed", "compensation"],
    )
    table = pd.DataFrame({COLUMN: [0.5, 0.5, 0.010, 0.008, 0.030, 0.024]}, index=index)
    text = posterior_deltoid_paragraph(table)
    # At 50 %: paper (0.010 + 0.030)/2 = 0.020, dynamic 0.016: −20 %; pretension rows left out.
    assert "0.0160 with the dynamic compensation against 0.0200 with the paper's (-20 %" in text
    assert "not installed" in posterior_deltoid_paragraph(table.assign(**{COLUMN: np.nan}))


def test_the_musculoskeletal_posterior_deltoid_is_read_off_the_same_trial() -> None:
    pytest.importorskip("mujoco")
    pytest.importorskip("myo_sim")
    participant = generate_cohort(0)[0]  # the study's default (simple) participant
    settings = ProtocolSettings(repetitions=2, lead_in_s=0.3, tail_s=0.1)
    trial = simulate_trial(participant, c.CONDITION_SUPPORT_50, "V3", model=MODEL, settings=settings, seed=3)
    value = musculoskeletal_posterior_deltoid(trial)
    twin = dataclasses.replace(
        trial, participant=dataclasses.replace(participant, muscles="musculoskeletal"), _cache={}
    )
    expected = twin.activations()["posterior_deltoid"].to_numpy()[phase_masks(trial)["lowering"]].mean()
    assert value == pytest.approx(expected)
    assert value > 0.0
    # The study's own (simple) activations are left as they were.
    assert trial.participant.muscles == "simple"
    simple = trial.activations()["posterior_deltoid"].to_numpy()[phase_masks(trial)["lowering"]].mean()
    assert simple != pytest.approx(value)
