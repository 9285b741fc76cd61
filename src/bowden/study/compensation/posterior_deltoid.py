"""The musculoskeletal participants' posterior deltoid while lowering, under either compensation.

The paper found the posterior deltoid more active while lowering at 50 % support than without the
suit (+32 %) and held the tension overshoot at the onset of lowering responsible: the cable pulls
against the lowering arm and the extensors push through it. The dynamic compensation removes most
of that overshoot, so the explanation predicts a quieter posterior deltoid with it. Here that is
tested on the comparison's own trials (identical participants, conditions, speeds and noise, either
compensation) with the musculoskeletal participants (``--muscles musculoskeletal``: MyoArm's
mechanics and static optimisation with the co-contraction row, issue 30), whatever muscle model
the study itself ran with: the activations are computed from each trial's own arm motion, tension
and corrections, so both muscle models can be read off the same trial.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from bowden import contracts as c
from bowden.errors import ParameterError
from bowden.sim.results import TrialSimulation, phase_masks

COLUMN = "posterior deltoid lowering, musculoskeletal"


def musculoskeletal_posterior_deltoid(trial: TrialSimulation) -> float:
    """Mean posterior deltoid activation while lowering of ``trial``'s musculoskeletal participant.

    NaN when the ``msk`` extra (MuJoCo, myo-sim) is not installed.
    """
    participant = dataclasses.replace(trial.participant, muscles="musculoskeletal")
    twin = dataclasses.replace(trial, participant=participant, _cache={})
    try:
        activation = twin.activations()["posterior_deltoid"].to_numpy()
    except ParameterError:  # MuJoCo or myo-sim missing: said in the paragraph
        return float("nan")
    return float(activation[phase_masks(trial)["lowering"]].mean())


def posterior_deltoid_paragraph(table: pd.DataFrame) -> str:
    """What the musculoskeletal participants' posterior deltoid says about the onset overshoot.

    ``table`` is the comparison's table (index condition label, speed, compensation) with
    :data:`COLUMN`.
    """
    column = table[COLUMN].astype(float)
    if column.isna().all():
        return ("The musculoskeletal participants' posterior deltoid is not shown: MuJoCo and myo-sim "
                "are not installed (pip install 'bowden[msk]').")
    fifty = c.CONDITION_LABELS[c.CONDITION_SUPPORT_50]
    at_fifty = column.xs(fifty, level=0) if fifty in column.index.get_level_values(0) else column
    means = at_fifty.groupby(level="compensation").mean()
    paper, dynamic = float(means.get("paper", np.nan)), float(means.get("dynamic", np.nan))
    change = 100.0 * (dynamic / paper - 1.0) if paper > 0.0 else float("nan")
    return (
        "Musculoskeletal participants (MyoArm, static optimisation with co-contraction; the column "
        f"“{COLUMN}”, computed from the same trials): at 50 % support the posterior deltoid while "
        f"lowering averages {dynamic:.4f} with the dynamic compensation against {paper:.4f} with the "
        f"paper's ({change:+.0f} %, mean over the speeds; simulated). If the tension overshoot at the "
        "lowering onset is what raises the posterior deltoid, as the paper proposes for its +32 %, "
        "the compensation that removes the overshoot should lower it."
    )
