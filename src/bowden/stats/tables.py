"""Tables like the paper's: descriptives with GLMM p-values, pairwise changes, colour-coded changes.

* :func:`effects_table` -- mean (SD) per condition x speed and the Type-III p-values of C, V and C x V
  (paper Tables S4, S7-S9).
* :func:`pairwise_table` -- change (SE), percent change and Holm p per comparison (Tables S5, S6, S10-S12).
* :func:`significance_table`, :func:`significance_html`, :func:`significance_styler` -- percent change of
  each condition comparison per outcome, green for a decrease and red for an increase, ``**`` for
  p < 0.001 and ``*`` for p < 0.05 (the paper's iEMG colour tables).
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np
import pandas as pd

from bowden.contracts import CONDITION_LABELS
from bowden.errors import ParameterError
from bowden.stats.analysis import OutcomeAnalysis

TERM_COLUMNS = {"condition": "p (C)", "speed": "p (V)", "condition:speed": "p (C x V)"}


def format_p(p: float, *, decimals: int = 3) -> str:
    """``"< 0.001"`` below 0.001, else the p-value with ``decimals`` digits (paper style)."""
    floor = 10.0**-decimals
    return f"< {floor:.{decimals}f}" if p < floor else f"{p:.{decimals}f}"


def significance_code(p: float) -> str:
    """``"**"`` for p < 0.001, ``"*"`` for p < 0.05, else ``""`` (the paper's codes)."""
    return "**" if p < 0.001 else "*" if p < 0.05 else ""


def _num(value: Any) -> float:
    """A pandas scalar as a float (pandas' stubs type cell access as any scalar)."""
    return float(value)


def _label(level: str) -> str:
    return CONDITION_LABELS.get(level, level)


def _contrast_label(row: pd.Series) -> str:
    return f"{_label(str(row['level_a']))}-{_label(str(row['level_b']))}"


def effects_table(
    analyses: Sequence[OutcomeAnalysis],
    *,
    spread: Literal["sd", "se"] = "sd",
    decimals: int = 3,
) -> pd.DataFrame:
    """Mean (spread) per condition x speed with the Type-III p-values, one block of rows per outcome.

    Each participant's repetitions are averaged first; mean and SD (or SE = SD / sqrt(n)) are then
    taken across participants.

    Returns
    -------
    pandas.DataFrame
        Index (outcome, speed); columns the condition labels, ``p (C)``, ``p (V)``, ``p (C x V)`` (strings;
        the p-values are on every row of an outcome's block).
    """
    if spread not in ("sd", "se"):
        raise ParameterError(f"spread must be 'sd' or 'se', got {spread!r}")
    rows = []
    for analysis in analyses:
        design = analysis.fit.design
        per_participant = (
            analysis.data.groupby(["condition", "speed", "participant"], sort=False)["value"]
            .mean()
            .reset_index()
        )
        stats_ = per_participant.groupby(["condition", "speed"], sort=False)["value"].agg(
            ["mean", "std", "count"]
        )
        p_values = {TERM_COLUMNS[t]: format_p(_num(analysis.tests.loc[t, "p"])) for t in TERM_COLUMNS}
        for speed in design.speeds:
            row: dict[str, Any] = {"outcome": analysis.name, "speed": speed}
            for cond in design.conditions:
                mean, sd, count = (_num(stats_.at[(cond, speed), k]) for k in ("mean", "std", "count"))
                value = sd if spread == "sd" else sd / np.sqrt(count)
                row[_label(cond)] = f"{mean:.{decimals}f} ({value:.{decimals}f})"
            row.update(p_values)
            rows.append(row)
    return pd.DataFrame(rows).set_index(["outcome", "speed"])


def pairwise_table(
    analyses: Sequence[OutcomeAnalysis],
    *,
    factor: Literal["condition", "speed"] = "condition",
    decimals: int = 3,
    only_if_significant: bool = True,
    alpha: float = 0.05,
) -> pd.DataFrame:
    """Change (SE), percent change and Holm-adjusted p of every pairwise comparison, one row per outcome.

    Parameters
    ----------
    factor:
        ``"condition"`` (later minus earlier, e.g. ``pre-no``) or ``"speed"`` (``V1-V2``).
    only_if_significant:
        As the paper: comparisons are shown only when the factor's Type-III test has p < ``alpha``;
        otherwise the cells read ``N/A``.

    Returns
    -------
    pandas.DataFrame
        Index outcome; columns (contrast, ``change`` | ``percent`` | ``p``).
    """
    if factor not in ("condition", "speed"):
        raise ParameterError(f"factor must be 'condition' or 'speed', got {factor!r}")
    records: dict[str, dict[tuple[str, str], str]] = {}
    for analysis in analyses:
        pairs = analysis.condition_pairs if factor == "condition" else analysis.speed_pairs
        show = not only_if_significant or _num(analysis.tests.loc[factor, "p"]) < alpha
        cells: dict[tuple[str, str], str] = {}
        for _, row in pairs.iterrows():
            label = _contrast_label(row)
            if show:
                cells[(label, "change")] = f"{row['estimate']:.{decimals}f} ({row['se']:.{decimals}f})"
                cells[(label, "percent")] = f"{row['percent_change']:.1f}"
                cells[(label, "p")] = format_p(float(row["p_holm"]), decimals=decimals)
            else:
                for part in ("change", "percent", "p"):
                    cells[(label, part)] = "N/A"
        records[analysis.name] = cells
    table = pd.DataFrame.from_dict(records, orient="index")
    table.columns = pd.MultiIndex.from_tuples([tuple(col) for col in table.columns])
    table.index.name = "outcome"
    return table


def significance_table(
    analyses: Sequence[OutcomeAnalysis],
    *,
    factor: Literal["condition", "speed"] = "condition",
    only_if_significant: bool = True,
    alpha: float = 0.05,
) -> pd.DataFrame:
    """Percent change and Holm p of each comparison per outcome (numbers behind the colour table).

    ``only_if_significant``: as the paper, pairwise p-values (and so the stars) are given only where the
    factor's Type-III test has p < ``alpha``; elsewhere ``p`` is NaN (a blank cell) and only the colour
    of the change remains.

    Returns
    -------
    pandas.DataFrame
        Index outcome; columns (contrast, ``percent`` | ``p``), floats.
    """
    if factor not in ("condition", "speed"):
        raise ParameterError(f"factor must be 'condition' or 'speed', got {factor!r}")
    records: dict[str, dict[tuple[str, str], float]] = {}
    for analysis in analyses:
        pairs = analysis.condition_pairs if factor == "condition" else analysis.speed_pairs
        show = not only_if_significant or _num(analysis.tests.loc[factor, "p"]) < alpha
        cells: dict[tuple[str, str], float] = {}
        for _, row in pairs.iterrows():
            cells[(_contrast_label(row), "percent")] = float(row["percent_change"])
            cells[(_contrast_label(row), "p")] = float(row["p_holm"]) if show else math.nan
        records[analysis.name] = cells
    table = pd.DataFrame.from_dict(records, orient="index")
    table.columns = pd.MultiIndex.from_tuples([tuple(col) for col in table.columns])
    table.index.name = "outcome"
    return table


def change_colour(percent: float, *, full_scale_percent: float = 60.0) -> str:
    """CSS colour of a percent change: green for a decrease, red for an increase, white for none.

    Saturation grows linearly with ``|percent|`` up to ``full_scale_percent`` (pure green/red), as the
    paper's colour bar (its cells run from RGB 255,255,255 to 0,255,0 and 255,0,0).
    """
    if not full_scale_percent > 0.0:
        raise ParameterError("full_scale_percent must be > 0")
    if not np.isfinite(percent):
        return "rgb(255,255,255)"
    k = round(255.0 * min(1.0, abs(percent) / full_scale_percent))
    return f"rgb({255 - k},255,{255 - k})" if percent < 0.0 else f"rgb(255,{255 - k},{255 - k})"


def _cells(table: pd.DataFrame) -> tuple[list[str], list[str]]:
    contrasts = list(dict.fromkeys(str(col[0]) for col in table.columns))
    return contrasts, [str(i) for i in table.index]


def significance_html(
    table: pd.DataFrame, *, full_scale_percent: float = 60.0, caption: str | None = None
) -> str:
    """HTML fragment (a ``<table>``) of :func:`significance_table`: coloured cells with ``**``/``*``.

    The percent change is in each cell's ``title`` (shown on hover) so the table stays compact.
    """
    contrasts, outcomes = _cells(table)
    cells = {}
    for outcome in outcomes:
        for contrast in contrasts:
            pct = _num(table.loc[outcome, (contrast, "percent")])
            p = _num(table.loc[outcome, (contrast, "p")])
            colour = change_colour(pct, full_scale_percent=full_scale_percent)
            cells[(outcome, contrast)] = (colour, significance_code(p), f"{pct:+.1f} %, p = {format_p(p)}")
    return coloured_cells_html(
        outcomes, contrasts, cells, caption=caption, index_name=str(table.index.name or "")
    )


def coloured_cells_html(
    outcomes: Sequence[str],
    contrasts: Sequence[str],
    cells: Mapping[tuple[str, str], tuple[str, str, str]],
    *,
    caption: str | None = None,
    index_name: str = "",
) -> str:
    """A colour table as HTML: one row per outcome, one column per contrast, each cell ``(CSS colour,
    text, hover title)`` (a missing cell is blank)."""
    out = ['<table class="bowden-significance" style="border-collapse:collapse">']
    if caption:
        out.append(f"<caption>{html.escape(caption)}</caption>")
    head = "".join(f'<th style="padding:2px 8px">{html.escape(c)}</th>' for c in contrasts)
    out.append(f"<thead><tr><th>{html.escape(index_name)}</th>{head}</tr></thead><tbody>")
    for outcome in outcomes:
        row = []
        for contrast in contrasts:
            colour, text, title = cells.get((outcome, contrast), ("#ffffff", "", ""))
            row.append(
                f'<td style="background:{colour};text-align:center;padding:2px 8px;font-weight:bold" '
                f'title="{html.escape(title)}">{html.escape(text)}</td>'
            )
        out.append(f'<tr><th style="text-align:left">{html.escape(outcome)}</th>{"".join(row)}</tr>')
    out.append("</tbody></table>")
    return "\n".join(out)


def significance_styler(table: pd.DataFrame, *, full_scale_percent: float = 60.0) -> Any:
    """The colour table as a pandas ``Styler`` (needs jinja2, which pandas' Styler requires).

    Cells hold the significance code; the background is the percent change colour.
    """
    try:
        import jinja2  # noqa: F401 - only checks that Styler can render
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(
            "significance_styler needs jinja2 (pip install jinja2); use significance_html"
        ) from exc
    contrasts, _ = _cells(table)
    codes = pd.DataFrame(
        {c: [significance_code(float(p)) for p in table[(c, "p")]] for c in contrasts}, index=table.index
    )
    colours = pd.DataFrame(
        {
            c: [
                f"background-color: {change_colour(float(v), full_scale_percent=full_scale_percent)}; "
                "text-align: center; font-weight: bold"
                for v in table[(c, "percent")]
            ]
            for c in contrasts
        },
        index=table.index,
    )
    return codes.style.apply(lambda _: colours, axis=None)
