"""The paper's questionnaire figures and the significance brackets of its box plots.

* :func:`nordic_body_map` — the modified Nordic questionnaire as a body map seen from behind (so the
  wearer's left is on the left), each site coloured by its median discomfort (1–7), one body per
  condition;
* :func:`questionnaire_boxplots` — Borg RPE (6–20) or perceived fatigue (1–7 per muscle group) per
  condition, one dot per participant, with the Bonferroni post-hoc comparisons that reached p < 0.05
  marked as the paper does (** p < 0.001, * p < 0.05);

Drawn on matplotlib's Agg canvas, as the other report figures.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Colormap, Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse, FancyBboxPatch

from bowden import contracts as c
from bowden.study.report.figures import CONDITION_COLOURS, significance_brackets

# Site centres and half sizes on a back view 0–10 wide, 0–20 high (head at the top); the wearer's left
# is on the viewer's left because the body is seen from behind.
_SITES: dict[str, tuple[float, float, float, float]] = {
    "upper_neck": (5.0, 17.2, 0.6, 0.45),
    "lower_neck": (5.0, 16.3, 0.7, 0.4),
    "left_shoulder": (3.4, 15.5, 0.9, 0.55),
    "right_shoulder": (6.6, 15.5, 0.9, 0.55),
    "upper_back": (5.0, 14.6, 1.3, 0.8),
    "middle_back": (5.0, 12.6, 1.2, 0.9),
    "lower_back": (5.0, 10.8, 1.2, 0.7),
    "hips": (5.0, 9.3, 1.5, 0.7),
    "left_upper_arm": (2.5, 13.7, 0.45, 1.2),
    "right_upper_arm": (7.5, 13.7, 0.45, 1.2),
    "left_elbow": (2.2, 12.0, 0.4, 0.4),
    "right_elbow": (7.8, 12.0, 0.4, 0.4),
    "left_forearm": (2.0, 10.6, 0.38, 1.0),
    "right_forearm": (8.0, 10.6, 0.38, 1.0),
    "left_wrist_hand": (1.8, 8.9, 0.42, 0.6),
    "right_wrist_hand": (8.2, 8.9, 0.42, 0.6),
}


def _figure(width: float, height: float) -> Figure:
    figure = Figure(figsize=(width, height), dpi=100, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def _present(answers: pd.DataFrame) -> list[str]:
    seen = set(answers["condition"])
    return [condition for condition in c.CONDITIONS if condition in seen]


def nordic_body_map(answers: pd.DataFrame, *, title: str = "Nordic questionnaire") -> Figure:
    """Median discomfort per site and condition on a back view.

    ``answers``: the long questionnaire table (``participant, condition, questionnaire, item, score``).
    """
    nordic = answers[answers["questionnaire"] == c.QUESTIONNAIRE_NORDIC]
    conditions = _present(nordic)
    medians = nordic.groupby(["condition", "item"])["score"].median()
    figure = _figure(2.6 * max(1, len(conditions)) + 0.8, 5.2)
    axes = figure.subplots(1, max(1, len(conditions)), squeeze=False)[0]
    colour_map = _colour_map()
    for ax, condition in zip(axes, conditions, strict=False):
        ax.add_patch(Ellipse((5.0, 18.6), 1.8, 2.2, facecolor="none", edgecolor="grey"))  # the head
        for site, (x, y, w, h) in _SITES.items():
            value = medians.get((condition, site), np.nan)
            colour = colour_map((value - 1.0) / 6.0) if np.isfinite(value) else (1.0, 1.0, 1.0, 1.0)
            ax.add_patch(
                FancyBboxPatch(
                    (x - w, y - h), 2 * w, 2 * h, boxstyle="round,pad=0.05,rounding_size=0.3",
                    facecolor=colour, edgecolor="grey", linewidth=0.6,
                )
            )
            if np.isfinite(value):
                ax.text(x, y, f"{value:g}", ha="center", va="center", fontsize=7)
        ax.set_xlim(0.5, 9.5)
        ax.set_ylim(8.0, 20.0)
        ax.set_aspect("equal")
        ax.axis("off")
        ax.set_title(c.CONDITION_LABELS.get(condition, condition))
        ax.text(0.6, 19.6, "L", fontsize=8, color="grey")
        ax.text(9.1, 19.6, "R", fontsize=8, color="grey")
    scale = figure.colorbar(
        _scalar_mappable(colour_map), ax=list(axes), shrink=0.7, label="median discomfort (1–7)"
    )
    scale.set_ticks([1, 4, 7])
    figure.suptitle(f"{title} (seen from behind)")
    return figure


def _colour_map() -> Colormap:
    return colormaps["YlOrRd"]


def _scalar_mappable(colour_map: Colormap) -> ScalarMappable:
    return ScalarMappable(norm=Normalize(1.0, 7.0), cmap=colour_map)


def questionnaire_boxplots(
    answers: pd.DataFrame,
    questionnaire: str,
    posthoc: dict[str, pd.DataFrame],
    *,
    ylabel: str,
    title: str,
) -> Figure:
    """One box per condition (per item for multi-item questionnaires), a dot per participant, brackets
    for the post-hoc comparisons with p < 0.05 (``posthoc`` keyed ``"questionnaire/item"``)."""
    data = answers[answers["questionnaire"] == questionnaire]
    items = list(dict.fromkeys(data["item"]))
    conditions = _present(data)
    figure = _figure(max(4.0, 2.4 * len(items)), 3.4)
    axes = figure.subplots(1, max(1, len(items)), sharey=True, squeeze=False)[0]
    rng = np.random.default_rng(0)  # jitter only
    for ax, item in zip(axes, items, strict=False):
        part = data[data["item"] == item]
        groups = [part[part["condition"] == cond]["score"].to_numpy(dtype=float) for cond in conditions]
        box = ax.boxplot(groups, patch_artist=True, widths=0.6, showfliers=False)
        for patch, condition in zip(box["boxes"], conditions, strict=True):
            patch.set_facecolor(CONDITION_COLOURS.get(condition, "#999999"))
            patch.set_alpha(0.35)
        for i, values in enumerate(groups, start=1):
            ax.scatter(i + rng.uniform(-0.12, 0.12, values.size), values, s=9, color="black", zorder=3)
        ax.set_xticks(range(1, len(conditions) + 1), [c.CONDITION_LABELS.get(x, x) for x in conditions])
        if len(items) > 1:
            ax.set_title(item.replace("_", " "))
        table = posthoc.get(f"{questionnaire}/{item}")
        if table is not None and not part.empty:
            positions = {condition: float(i) for i, condition in enumerate(conditions, start=1)}
            p_values = table["p"].to_numpy(dtype=float)
            pairs = zip(table["group_a"].astype(str), table["group_b"].astype(str), p_values, strict=True)
            top = float(part["score"].to_numpy(dtype=float).max())
            significance_brackets(ax, positions, [(a, b, float(p)) for a, b, p in pairs], top)
    axes[0].set_ylabel(ylabel)
    figure.suptitle(title)
    return figure
