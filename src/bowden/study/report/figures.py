"""The report's figures, drawn like the paper's, on matplotlib's Agg canvas (no pyplot state)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bowden.contracts import CONDITION_LABELS, CONDITIONS, SPEED_PEAK_DEG_S, SPEEDS
from bowden.stats.tables import significance_code

# The paper's colours: no suit purple, pretension blue, 25 % red, 50 % yellow.
CONDITION_COLOURS = {
    "no_suit": "#7b3294",
    "pretension": "#2b83ba",
    "support_25": "#d7191c",
    "support_50": "#e6b800",
}


def _figure(width: float, height: float) -> Figure:
    figure = Figure(figsize=(width, height), dpi=100, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def participant_curves(curves: pd.DataFrame, participant: str) -> Figure:
    """One participant's mean ± SD over the kept repetitions (paper's single-participant figure).

    Rows: elevation, shoulder torque and cable tension (each condition's desired torque and tension
    dashed in the condition's colour: pretension, 25 % and 50 % support each follow their own), EMG of
    the anterior and posterior deltoid; columns: speeds.
    """
    rows = (
        ("elevation_rad", None, "elevation (deg)", np.degrees),
        ("torque_nm", "desired_torque_nm", "torque (Nm)", None),
        ("tension_n", "desired_tension_n", "tension (N)", None),
        ("emg_anterior_deltoid", None, "ant. deltoid (norm.)", None),
        ("emg_posterior_deltoid", None, "post. deltoid (norm.)", None),
    )
    data = curves[curves["participant"] == participant]
    figure = _figure(11.0, 12.0)
    axes = figure.subplots(len(rows), len(SPEEDS), sharex=True, squeeze=False)
    for col, speed in enumerate(SPEEDS):
        axes[0, col].set_title(f"{speed} ({SPEED_PEAK_DEG_S[speed]:.0f} °/s)")
        for row, (signal, reference, label, scale) in enumerate(rows):
            ax = axes[row, col]
            for condition in CONDITIONS:
                colour = CONDITION_COLOURS[condition]
                _band(ax, data, condition, speed, signal, scale, colour)
                if reference is not None:  # each condition has its own desired torque and tension
                    _band(ax, data, condition, speed, reference, scale, colour, dashed=True)
            if col == 0:
                ax.set_ylabel(label)
            if row == len(rows) - 1:
                ax.set_xlabel("normalised time (%)")
    handles = [
        axes[0, 0].plot([], [], color=CONDITION_COLOURS[c], label=CONDITION_LABELS[c])[0] for c in CONDITIONS
    ]
    handles.append(axes[0, 0].plot([], [], color="grey", linestyle="--", label="desired (its colour)")[0])
    figure.legend(handles=handles, loc="outside upper center", ncols=len(handles))
    return figure


def _band(
    ax: Axes,
    data: pd.DataFrame,
    condition: str,
    speed: str,
    signal: str,
    scale: object,
    colour: str,
    dashed: bool = False,
) -> None:
    part = data[(data["condition"] == condition) & (data["speed"] == speed) & (data["signal"] == signal)]
    if part.empty or part["mean"].isna().all():
        return
    x = 100.0 * part["normalised_time"].to_numpy()
    mean, sd = part["mean"].to_numpy(), part["sd"].fillna(0.0).to_numpy()
    if callable(scale):
        mean, sd = scale(mean), scale(sd)
    ax.plot(x, mean, color=colour, linestyle="--" if dashed else "-", linewidth=1.2)
    if not dashed:
        ax.fill_between(x, mean - sd, mean + sd, color=colour, alpha=0.2, linewidth=0)


def condition_boxplots(
    data: pd.DataFrame,
    ylabel: str,
    title: str,
    comparisons: Sequence[tuple[str, str, float]] = (),
    paper_means: Mapping[tuple[str, str], float] | None = None,
) -> Figure:
    """Boxplots per speed and condition of participants' means, one dot per participant (paper style).

    ``data``: columns participant, condition, speed, value (repetition level; averaged here).
    ``comparisons``: (condition, condition, p) of the pairwise comparisons over the speeds grouped;
    those with p < 0.05 are marked on every panel, as the paper marks them.
    ``paper_means``: (condition, speed) -> the paper's mean, drawn as a marker beside each box.
    """
    means = data.groupby(["participant", "condition", "speed"], as_index=False)["value"].mean()
    figure = _figure(10.0, 3.4)
    axes = figure.subplots(1, len(SPEEDS), sharey=True, squeeze=False)[0]
    rng = np.random.default_rng(0)  # jitter only; fixed so the report is reproducible
    present = [c for c in CONDITIONS if c in set(means["condition"])]
    for ax, speed in zip(axes, SPEEDS, strict=True):
        groups = [
            means[(means["speed"] == speed) & (means["condition"] == c)]["value"].to_numpy() for c in present
        ]
        box = ax.boxplot(groups, patch_artist=True, widths=0.6, showfliers=False)
        for patch, condition in zip(box["boxes"], present, strict=True):
            patch.set_facecolor(CONDITION_COLOURS[condition])
            patch.set_alpha(0.35)
        for i, values in enumerate(groups, start=1):
            ax.scatter(i + rng.uniform(-0.12, 0.12, values.size), values, s=9, color="black", zorder=3)
        if paper_means:
            marked = [(i, paper_means[(c, speed)]) for i, c in enumerate(present, start=1)
                      if (c, speed) in paper_means]
            if marked:
                ax.scatter([i + 0.38 for i, _ in marked], [v for _, v in marked], marker="D", s=22,
                           color="white", edgecolors="black", zorder=4, label="paper mean")
        ax.set_xticks(range(1, len(present) + 1), [CONDITION_LABELS[c] for c in present])
        ax.set_title(f"{speed} ({SPEED_PEAK_DEG_S[speed]:.0f} °/s)")
    if comparisons and not means.empty:
        positions = {condition: float(i) for i, condition in enumerate(present, start=1)}
        top = float(means["value"].max())
        low, high = axes[0].get_ylim()  # shared by the panels: one step for all
        for ax in axes:
            significance_brackets(ax, positions, comparisons, top, step=0.1 * (high - low))
    axes[0].set_ylabel(ylabel)
    if paper_means:
        axes[-1].legend(loc="best", fontsize=7)
    figure.suptitle(title)
    return figure


def significance_brackets(
    ax: Axes,
    positions: dict[str, float],
    comparisons: Sequence[tuple[str, str, float]],
    top: float,
    step: float | None = None,
) -> None:
    """Brackets between condition positions for comparisons with p < 0.05, stacked above ``top``.

    ``step`` is the height of one bracket level (default: a tenth of the axes' current range); give
    the same to axes that share their y axis, so the brackets line up.
    """
    shown = [(a, b, p) for a, b, p in comparisons if p < 0.05 and a in positions and b in positions]
    low, high = ax.get_ylim()
    step = step if step is not None else 0.1 * (high - low)
    for level, (a, b, p) in enumerate(shown):
        y = top + step * (level + 0.5)
        x1, x2 = sorted((positions[a], positions[b]))
        ax.plot([x1, x1, x2, x2], [y - 0.2 * step, y, y, y - 0.2 * step], color="black", linewidth=0.8)
        ax.text(0.5 * (x1 + x2), y + 0.02 * step, significance_code(p), ha="center", va="bottom", fontsize=8)
    if shown:
        ax.set_ylim(low, max(high, top + step * (len(shown) + 0.8)))
