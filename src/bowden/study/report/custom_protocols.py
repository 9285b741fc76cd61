"""A lab's own conditions and speeds in ``bowden analyze``: analysed, reported, kept apart.

The paper's comparisons (GLMMs over condition × speed, Friedman tests, its tables and figures) are
made on the paper's four conditions and three speeds only, so that a lab's ``support_70`` or ``V4``
(:mod:`bowden.protocol.catalogue`) neither changes the reference levels nor breaks a layout made
for the paper. Their trials are analysed like every other (the outcome table holds them), described
in a section of their own (support, peak speed, tracking and smoothness per condition and speed,
the median Borg RPE), and each is named in the report's notes, one line each.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from bowden.analysis import StudyOutcomes
from bowden.analysis.trial_outcomes import ELEVATION_RMSE, SPARC, TENSION_RMSE
from bowden.contracts import BORG_RPE_ITEM, CONDITIONS, QUESTIONNAIRE_BORG_RPE, SPEEDS
from bowden.store.study_store import StudyStore
from bowden.study.report.html import HtmlDocument


@dataclass(frozen=True)
class CustomDefinitions:
    """What a store's trials recorded of the custom names: support per condition, peak per speed."""

    supports: dict[str, float]
    peaks_deg_s: dict[str, float]


def custom_definitions(store: StudyStore) -> CustomDefinitions:
    """The support of each custom condition and the peak (°/s) of each custom speed, as recorded."""
    return CustomDefinitions(
        supports={name: support for name, support in store.condition_supports() if name not in CONDITIONS},
        peaks_deg_s={name: peak for name, peak in store.speed_peaks() if name not in SPEEDS},
    )


def is_paper(frame: pd.DataFrame) -> pd.Series:
    """Rows of the paper's conditions at the paper's speeds (a frame without speeds: conditions only)."""
    mask = frame["condition"].isin(CONDITIONS)
    if "speed" in frame.columns:
        mask &= frame["speed"].isin(SPEEDS)
    return mask


def paper_part(outcomes: StudyOutcomes) -> StudyOutcomes:
    """The outcomes and curves of the paper's conditions and speeds (what its comparisons take)."""
    return dataclasses.replace(
        outcomes,
        outcomes=outcomes.outcomes[is_paper(outcomes.outcomes)].reset_index(drop=True),
        curves=outcomes.curves[is_paper(outcomes.curves)].reset_index(drop=True),
    )


def custom_notes(outcomes: pd.DataFrame, definitions: CustomDefinitions) -> list[str]:
    """One line per custom condition and speed in the analysed outcomes."""
    notes = []
    for condition in sorted(set(outcomes["condition"]) - set(CONDITIONS)):
        support = definitions.supports.get(condition, math.nan)
        notes.append(
            f"Condition {condition} (custom, support {support:.0%}): analysed and described under "
            "'Conditions and speeds beyond the paper'; left out of the paper's comparisons"
        )
    for speed in sorted(set(outcomes["speed"]) - set(SPEEDS)):
        peak = definitions.peaks_deg_s.get(speed, math.nan)
        notes.append(
            f"Speed {speed} (custom, {peak:g} °/s peak): analysed and described under "
            "'Conditions and speeds beyond the paper'; left out of the paper's comparisons"
        )
    return notes


def custom_table(
    outcomes: pd.DataFrame, questionnaires: pd.DataFrame, definitions: CustomDefinitions
) -> pd.DataFrame | None:
    """Per custom (condition, speed): support, peak, participants, repetitions, mean tracking measures."""
    data = outcomes[~is_paper(outcomes)]
    if data.empty:
        return None
    entire = data[data["phase"] == "entire"]
    rows = []
    for (condition, speed), group in entire.groupby(["condition", "speed"], sort=True):
        def mean_of(measure: str, frame: pd.DataFrame = group) -> float:
            values = frame.loc[frame["measure"] == measure, "value"].dropna()
            return float(values.mean()) if len(values) else math.nan

        support = definitions.supports.get(str(condition))
        peak = definitions.peaks_deg_s.get(str(speed))
        rpe = questionnaires[
            (questionnaires["condition"] == condition)
            & (questionnaires["questionnaire"] == QUESTIONNAIRE_BORG_RPE)
            & (questionnaires["item"] == BORG_RPE_ITEM)
        ]["score"] if not questionnaires.empty else pd.Series(dtype=float)
        rows.append({
            "condition": condition,
            "speed": speed,
            "support": "paper's" if condition in CONDITIONS else f"{support:.0%}" if support else "?",
            "peak (°/s)": "paper's" if speed in SPEEDS else f"{peak:g}" if peak else "?",
            "participants": group["participant"].nunique(),
            "repetitions": int(group.loc[group["measure"] == ELEVATION_RMSE, "repetition"].count()),
            "elevation RMSE (deg)": float(np.degrees(mean_of(ELEVATION_RMSE))),
            "SPARC": mean_of(SPARC),
            "tension RMSE (N)": mean_of(TENSION_RMSE),
            "median Borg RPE": float(rpe.median()) if len(rpe) else math.nan,
        })
    return pd.DataFrame(rows).set_index(["condition", "speed"])


def custom_section(document: HtmlDocument, table: pd.DataFrame | None) -> None:
    """The report's section on the custom conditions and speeds (nothing when there are none)."""
    if table is None:
        return
    document.heading("Conditions and speeds beyond the paper")
    document.paragraph(
        "Conditions and speeds this study defined itself (bowden serve or bowden run with "
        "--define-condition / --define-speed). Their trials are analysed like the others and are in "
        "the outcome table; the paper's comparisons above (GLMMs, Friedman tests, its tables and "
        "figures) take the paper's four conditions and three speeds only. Means over participants "
        "and repetitions, whole movement."
    )
    document.table(table, "Custom conditions and speeds: means of the whole movement", "{:.3g}")
