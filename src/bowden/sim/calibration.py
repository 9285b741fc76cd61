"""The virtual cohort's muscles against the paper's, quickly: iEMG changes from the activations.

The synthetic sEMG's envelope follows ``gain · activation`` above the amplifier's noise floor
(:mod:`bowden.sim.emg`), so the changes in iEMG between conditions can be read off the activations
without synthesising and processing 2 kHz signals. This is the fast loop the participants' parameters
were chosen with (``scripts/participant_calibration.py``, docs/simulation.md); the numbers that
count are those of the full pipeline (``bowden study``'s report).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from bowden import contracts as c
from bowden.errors import ParameterError
from bowden.sim.emg import BASELINE_NOISE_V, FULL_ACTIVATION_V
from bowden.sim.results import TrialSimulation

PHASE_BOUNDS = {"raising": (0.0, 0.5), "lowering": (0.5, 1.0)}


def activation_iemg_rows(trial: TrialSimulation) -> list[dict[str, Any]]:
    """Per kept repetition (the first is dropped), phase and muscle: the envelope's mean and peak."""
    act = trial.activations()[list(c.MUSCLES)].to_numpy()
    gains = np.asarray(trial.participant.emg_gains)
    factors = trial.emg_amplitude_factors()  # the trial's and each repetition's, as the sEMG has them
    envelope = np.hypot(act * factors * gains * FULL_ACTIVATION_V, BASELINE_NOISE_V)
    rep, frac = trial.repetition_index(), trial.cycle_fraction()
    rows: list[dict[str, Any]] = []
    for r in range(1, trial.repetitions):
        peak = envelope[rep == r].max(axis=0)
        for phase, (low, high) in PHASE_BOUNDS.items():
            mean = envelope[(rep == r) & (frac >= low) & (frac < high)].mean(axis=0)
            rows.extend(
                {"participant": trial.participant.participant_id, "condition": trial.condition,
                 "speed": trial.speed, "phase": phase, "muscle": muscle, "mean": mean[m], "peak": peak[m]}
                for m, muscle in enumerate(c.MUSCLES)
            )
    return rows


def iemg_changes(rows: pd.DataFrame) -> pd.DataFrame:
    """% change of the normalised iEMG against no suit per phase, muscle and suit condition.

    Normalised to each participant's no-suit peak at that speed, as the analysis does; the change is
    the mean over speeds of the cohort means' ratio, as the report's departures compute the paper's.
    Columns: phase, muscle, condition, change_pct and one column per speed.
    """
    no_suit = rows[rows["condition"] == c.CONDITION_NO_SUIT]
    reference = no_suit.groupby(["participant", "speed", "muscle"])["peak"].mean().rename("reference")
    rows = rows.join(reference, on=["participant", "speed", "muscle"])
    means = (rows["mean"] / rows["reference"]).groupby(
        [rows["phase"], rows["muscle"], rows["condition"], rows["speed"]]
    ).mean()
    speeds = sorted(rows["speed"].unique())
    out = []
    for phase in PHASE_BOUNDS:
        for muscle in c.MUSCLES:
            for condition in c.CONDITIONS[1:]:
                changes = {
                    speed: 100.0 * (means[(phase, muscle, condition, speed)]
                                    / means[(phase, muscle, c.CONDITION_NO_SUIT, speed)] - 1.0)
                    for speed in speeds
                }
                out.append({"phase": phase, "muscle": muscle, "condition": condition,
                            "change_pct": float(np.mean(list(changes.values()))), **changes})
    return pd.DataFrame(out)


def implied_dispersion(
    condition_log_means: Sequence[float], p: float, *, n_per_condition: int, residual_df: int
) -> float:
    """The gamma dispersion φ (Var(y) = φμ²) under which a GLMM's condition test on these means has ``p``.

    For a balanced design with a log link, each condition's log mean is estimated with variance
    φ/n (the participant's intercept cancels in the contrasts), so the condition test's
    F = n·Σ(ηᵢ − η̄)²/(k − 1)/φ on (k − 1, ``residual_df``) degrees of freedom: φ is that sum over
    the F whose upper tail is ``p``. This is how the sEMG amplitude's repetition spread was set from
    the paper's Table S7 (docs/simulation.md, "Amplitude variability"; ``scripts/emg_dispersion.py``).
    """
    eta = np.asarray(condition_log_means, dtype=np.float64)
    if eta.ndim != 1 or eta.size < 2 or not np.isfinite(eta).all():
        raise ParameterError("condition_log_means needs two or more finite values")
    if not (0.0 < p < 1.0 and n_per_condition > 0 and residual_df > 0):
        raise ParameterError("p must be in (0, 1) and the counts positive")
    k = eta.size
    between = n_per_condition * float(np.sum((eta - eta.mean()) ** 2)) / (k - 1)
    return between / float(stats.f.isf(p, k - 1, residual_df))
