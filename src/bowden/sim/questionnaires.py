"""Questionnaire answers of virtual participants, driven by what they went through in each condition.

The paper (supplement, Questionnaires) used a 16-site modified Nordic questionnaire of discomfort
(7-point Likert, 1 = no discomfort), the Borg RPE scale (6–20) and a 6-site muscular fatigue diagram
(7-point Likert). It found mild discomfort at the upper neck and moderate discomfort at the right
shoulder growing with support (cuff pressure) and no change of exertion or fatigue (floor effect).
Here a latent score per item is a baseline, plus cuff pressure (mean anchor tension) at the neck and
shoulder sites, plus effort (mean agonist activation) for exertion and fatigue, plus the participant's
response style and noise, rounded and clipped to the scale.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from bowden.contracts import (
    BORG_RPE_ITEM,
    FATIGUE_SITES,
    MUSCLES,
    NORDIC_SITES,
    QUESTIONNAIRE_BORG_RPE,
    QUESTIONNAIRE_FATIGUE,
    QUESTIONNAIRE_NORDIC,
)

if TYPE_CHECKING:
    from bowden.sim.participants import VirtualParticipant
    from bowden.sim.results import TrialSimulation

# Sites pressed by the shoulder cuff and the backpack frame, with latent points per 10 N of tension.
_PRESSURE_POINTS_PER_10N = {"upper_neck": 0.55, "right_shoulder": 0.75, "lower_neck": 0.25, "upper_back": 0.2}
_AGONISTS = [MUSCLES.index(m) for m in ("anterior_deltoid", "medial_deltoid", "trapezius")]


def _likert(latent: float, low: int, high: int) -> int:
    return int(np.clip(np.rint(latent), low, high))


@dataclass(frozen=True)
class TrialLoad:
    """What a trial leaves for the questionnaires: the cuff's mean tension and the wearer's effort.

    A few numbers instead of the whole trial, so that trials simulated in worker processes need not
    be sent back whole to answer the questionnaires.
    """

    participant: VirtualParticipant
    condition: str
    tension_n: float | None  # mean true anchor tension, None without the suit
    effort: float  # mean activation of the agonists


def trial_load(trial: TrialSimulation) -> TrialLoad:
    """The questionnaire's inputs from one simulated trial."""
    tension = float(np.nanmean(trial.signals["true_tension_n"])) if trial.wears_suit else None
    effort = float(trial.activations().iloc[:, 1:].to_numpy()[:, _AGONISTS].mean())
    return TrialLoad(trial.participant, trial.condition, tension, effort)


def questionnaire_answers(trials: Sequence[TrialSimulation], *, seed: int) -> pd.DataFrame:
    """Answers after each condition: columns ``participant_id, condition, questionnaire, item, score``.

    ``questionnaire`` is ``"nordic"`` (items :data:`bowden.contracts.NORDIC_SITES`, 1–7), ``"borg_rpe"`` (item
    ``"rpe"``, 6–20) or ``"fatigue"`` (items :data:`bowden.contracts.FATIGUE_SITES`, 1–7).
    """
    return answers_from_loads([trial_load(trial) for trial in trials], seed=seed)


def answers_from_loads(loads: Sequence[TrialLoad], *, seed: int) -> pd.DataFrame:
    """:func:`questionnaire_answers` from the trials' :class:`TrialLoad` (the same answers)."""
    groups: dict[tuple[str, str], list[TrialLoad]] = {}
    for load in loads:
        groups.setdefault((load.participant.participant_id, load.condition), []).append(load)
    rows: list[tuple[str, str, str, str, int]] = []
    for (pid, condition), group in groups.items():
        participant = group[0].participant
        rng = np.random.default_rng([seed, int(pid.lstrip("P") or 0), len(condition), 7])
        tensions = [t.tension_n for t in group if t.tension_n is not None]
        tension = float(np.mean(tensions)) if tensions else 0.0
        effort = float(np.mean([t.effort for t in group]))
        style = 0.35 * participant.discomfort_sensitivity
        for site in NORDIC_SITES:
            pressure = _PRESSURE_POINTS_PER_10N.get(site, 0.0) * tension / 10.0
            latent = 1.0 + pressure * (1.0 + 0.3 * participant.discomfort_sensitivity) + style
            score = _likert(latent + 0.4 * rng.standard_normal(), 1, 7)
            rows.append((pid, condition, QUESTIONNAIRE_NORDIC, site, score))
        rpe = 8.0 + 12.0 * effort + 0.8 * participant.discomfort_sensitivity + 1.2 * rng.standard_normal()
        rows.append((pid, condition, QUESTIONNAIRE_BORG_RPE, BORG_RPE_ITEM, _likert(rpe, 6, 20)))
        for site in FATIGUE_SITES:
            latent = 1.4 + 4.0 * effort + style + 0.5 * rng.standard_normal()
            rows.append((pid, condition, QUESTIONNAIRE_FATIGUE, site, _likert(latent, 1, 7)))
    return pd.DataFrame(rows, columns=["participant_id", "condition", "questionnaire", "item", "score"])
