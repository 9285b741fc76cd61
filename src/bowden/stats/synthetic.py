"""Synthetic repeated-measures data from a gamma GLMM, for tests, fixtures and benchmarks.

The generator draws exactly from the model that :func:`bowden.stats.fit_gamma_glmm` fits, so fits
on its output can be checked against the true parameters and against R on the same numbers.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from bowden.contracts import CONDITIONS, SPEEDS
from bowden.errors import ParameterError


@dataclass(frozen=True, kw_only=True)
class GammaGlmmDesign:
    """True parameters of a gamma GLMM with log link and a random intercept per participant.

    ``log E[y] = intercept + condition_effect[c] + speed_effect[v] + interaction[c][v] + b_i``,
    ``b_i ~ N(0, participant_sd**2)``, ``y ~ Gamma(shape, scale = mean / shape)``.

    Attributes
    ----------
    n_participants, n_repetitions:
        Participants and repetitions per condition x speed cell.
    intercept:
        Log of the outcome in the first condition and speed for a typical participant.
    condition_effect, speed_effect:
        Additive effects on the log scale, one per level (first level conventionally 0).
    interaction:
        Log-scale interaction, ``len(conditions)`` rows of ``len(speeds)`` values.
    participant_sd:
        Standard deviation of the random intercept (log scale).
    shape:
        Gamma shape; the dispersion is ``1 / shape`` (coefficient of variation ``shape**-0.5``).
    conditions, speeds:
        Level names.
    """

    n_participants: int = 17
    n_repetitions: int = 9
    intercept: float = float(np.log(0.45))
    condition_effect: tuple[float, ...] = (0.0, -0.03, -0.05, -0.08)
    speed_effect: tuple[float, ...] = (0.0, 0.03, 0.01)
    interaction: tuple[tuple[float, ...], ...] = (
        (0.0, 0.0, 0.0),
        (0.0, 0.02, -0.02),
        (0.0, 0.03, 0.01),
        (0.0, -0.01, 0.03),
    )
    participant_sd: float = 0.25
    shape: float = 9.0
    conditions: tuple[str, ...] = field(default=CONDITIONS)
    speeds: tuple[str, ...] = field(default=SPEEDS)

    def __post_init__(self) -> None:
        if self.n_participants < 2:
            raise ParameterError("n_participants must be at least 2")
        if self.n_repetitions < 1:
            raise ParameterError("n_repetitions must be at least 1")
        if len(self.condition_effect) != len(self.conditions):
            raise ParameterError("condition_effect needs one value per condition")
        if len(self.speed_effect) != len(self.speeds):
            raise ParameterError("speed_effect needs one value per speed")
        if len(self.interaction) != len(self.conditions) or any(
            len(row) != len(self.speeds) for row in self.interaction
        ):
            raise ParameterError("interaction must be len(conditions) rows of len(speeds) values")
        if not self.participant_sd >= 0.0:
            raise ParameterError("participant_sd must be >= 0")
        if not self.shape > 0.0:
            raise ParameterError("shape must be > 0")


def simulate_gamma_glmm(
    design: GammaGlmmDesign | None = None,
    *,
    seed: int = 0,
    drop_fraction: float = 0.0,
    participant_prefix: str = "P",
) -> pd.DataFrame:
    """Draw one study's tidy outcome table from a gamma GLMM.

    Parameters
    ----------
    design:
        True parameters; the defaults give iEMG-like values around 0.3-0.5.
    seed:
        Seed of ``numpy.random.default_rng``.
    drop_fraction:
        Fraction of rows removed at random for an unbalanced design (every cell keeps at least one
        row per participant).
    participant_prefix:
        Participant ids are ``f"{prefix}{k:02d}"``.

    Returns
    -------
    pandas.DataFrame
        Columns ``participant, condition, speed, repetition, value`` (value > 0).
    """
    design = design or GammaGlmmDesign()
    if not 0.0 <= drop_fraction < 1.0:
        raise ParameterError("drop_fraction must be in [0, 1)")
    rng = np.random.default_rng(seed)
    n_c, n_v = len(design.conditions), len(design.speeds)
    b = rng.normal(0.0, design.participant_sd, design.n_participants)
    p_idx, c_idx, v_idx, r_idx = np.meshgrid(
        np.arange(design.n_participants),
        np.arange(n_c),
        np.arange(n_v),
        np.arange(design.n_repetitions),
        indexing="ij",
    )
    p_idx, c_idx, v_idx, r_idx = (a.ravel() for a in (p_idx, c_idx, v_idx, r_idx))
    inter = np.asarray(design.interaction, dtype=float)
    eta = (
        design.intercept
        + np.asarray(design.condition_effect)[c_idx]
        + np.asarray(design.speed_effect)[v_idx]
        + inter[c_idx, v_idx]
        + b[p_idx]
    )
    mean = np.exp(eta)
    value = rng.gamma(design.shape, mean / design.shape)
    keep = np.ones(value.size, dtype=bool)
    if drop_fraction > 0.0:
        keep = rng.random(value.size) >= drop_fraction
        # The first repetition of every participant x cell stays so that no cell becomes empty.
        keep |= r_idx == 0
    frame = pd.DataFrame(
        {
            "participant": [f"{participant_prefix}{k + 1:02d}" for k in p_idx[keep]],
            "condition": np.asarray(design.conditions, dtype=object)[c_idx[keep]],
            "speed": np.asarray(design.speeds, dtype=object)[v_idx[keep]],
            "repetition": r_idx[keep] + 1,
            "value": value[keep],
        }
    )
    return frame.reset_index(drop=True)
