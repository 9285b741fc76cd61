"""Questionnaire results as the paper's Results text gives them (subsection "Questionnaires").

The paper gives p-values only: Friedman tests across conditions for the Nordic sites it names, the RPE
and each fatigue site, and the Bonferroni post-hoc comparisons that reached significance (every one an
increase of discomfort with the suit). Its figures (fig:nordic_results, fig:rpe_fatigue) hold the
medians and box plots as images, so no median is published as a number. The Discussion calls the
neck finding "upper neck", the Results "lower neck"; the Results' p-values are stored under
``lower_neck`` (docs/design.md lists this among the paper's ambiguities).
"""

from __future__ import annotations

import pandas as pd

from bowden.study.paper_values.pvalue import P
from bowden.study.paper_values.questionnaire_data import NORDIC_PAIRS, QUESTIONNAIRE_P


def questionnaire_p(questionnaire: str, item: str) -> P | None:
    """The paper's Friedman p of one item, or None where the text gives none."""
    return QUESTIONNAIRE_P.get((questionnaire, item))


def questionnaire_results() -> pd.DataFrame:
    """Every item with a published p: questionnaire, item, p (a :class:`P`), significant."""
    rows = [(q, item, p, p.significant()) for (q, item), p in QUESTIONNAIRE_P.items()]
    return pd.DataFrame(rows, columns=["questionnaire", "item", "p", "significant"])


def nordic_pairs() -> pd.DataFrame:
    """The Nordic post-hoc comparisons the text reports: item, from, to, direction, p."""
    rows = [(item, a, b, d, p) for (item, a, b), (d, p) in NORDIC_PAIRS.items()]
    return pd.DataFrame(rows, columns=["item", "from", "to", "direction", "p"])
