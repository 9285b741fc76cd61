"""The paper's questionnaire figures and significance marks: what they draw, checked on the artists."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import FancyBboxPatch

from bowden import contracts as c
from bowden.study.report.figures import significance_brackets
from bowden.study.report.questionnaire_figures import nordic_body_map, questionnaire_boxplots


def answers() -> pd.DataFrame:
    rows = []
    for p in range(5):
        for i, condition in enumerate(c.CONDITIONS):
            for site in c.NORDIC_SITES:
                score = 1 + (i + p % 2 if site == "right_shoulder" else 0)
                rows.append((f"P{p}", condition, c.QUESTIONNAIRE_NORDIC, site, score))
            rows.append((f"P{p}", condition, c.QUESTIONNAIRE_BORG_RPE, c.BORG_RPE_ITEM, 12 - i + p % 3))
    return pd.DataFrame(rows, columns=["participant", "condition", "questionnaire", "item", "score"])


def test_the_body_map_colours_each_site_by_its_median_and_shows_it() -> None:
    figure = nordic_body_map(answers())
    body_axes = [ax for ax in figure.axes if ax.get_title() in ("no", "pre", "25%", "50%")]
    assert [ax.get_title() for ax in body_axes] == ["no", "pre", "25%", "50%"]
    for index, ax in enumerate(body_axes):
        assert sum(isinstance(patch, FancyBboxPatch) for patch in ax.patches) == len(c.NORDIC_SITES)
        labels = [text.get_text() for text in ax.texts]
        # right shoulder: scores 1 + i and 2 + i over five participants, median 1 + i
        assert labels.count(f"{1 + index:g}") >= 1
    shoulder = [t for t in body_axes[3].texts if t.get_text() == "4"]
    assert shoulder and shoulder[0].get_position()[0] > 5.0  # the right side, seen from behind


def test_brackets_mark_only_comparisons_below_005() -> None:
    figure = Figure()
    FigureCanvasAgg(figure)
    ax = figure.add_subplot()
    ax.set_ylim(0.0, 1.0)
    positions = {"no_suit": 1.0, "pretension": 2.0, "support_50": 3.0}
    significance_brackets(
        ax, positions, [("no_suit", "pretension", 0.0005), ("no_suit", "support_50", 0.04),
                        ("pretension", "support_50", 0.2)], top=0.9,
    )
    assert len(ax.lines) == 2
    assert sorted(t.get_text() for t in ax.texts) == ["*", "**"]
    assert ax.get_ylim()[1] > 0.9


def test_rpe_boxplots_mark_the_posthoc_that_reached_significance() -> None:
    posthoc = {
        f"{c.QUESTIONNAIRE_BORG_RPE}/{c.BORG_RPE_ITEM}": pd.DataFrame(
            {"group_a": ["no_suit", "no_suit"], "group_b": ["support_50", "pretension"], "p": [0.001, 0.5]}
        )
    }
    figure = questionnaire_boxplots(answers(), c.QUESTIONNAIRE_BORG_RPE, posthoc, ylabel="RPE", title="t")
    ax = figure.axes[0]
    assert [t.get_text() for t in ax.texts] == ["*"]  # p = 0.001 is "*" ([0.001, 0.05)), 0.5 unmarked
    assert np.isclose(ax.lines[-1].get_xdata()[-1], 4.0)  # the bracket reaches the 50 % box
