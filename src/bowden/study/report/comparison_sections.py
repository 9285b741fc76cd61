"""The report's sections that set the study against the paper: where it departs, and the questionnaires."""

from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING

from bowden.contracts import QUESTIONNAIRE_BORG_RPE, QUESTIONNAIRE_FATIGUE, QUESTIONNAIRE_NORDIC
from bowden.study import paper_values
from bowden.study.departures.calibration import CALIBRATED, calibration_table
from bowden.study.departures.table import all_departures, departure_summary, family_summary
from bowden.study.report import questionnaire_figures
from bowden.study.report.html import HtmlDocument

if TYPE_CHECKING:
    from bowden.study.report.build import ReportInputs


def departures_section(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """Every outcome the paper reports beside the study's, what differs, and what was calibrated."""
    table = all_departures(inputs.outcomes.outcomes, inputs.statistics)
    doc.heading(f"Where the {'simulation' if inputs.simulated else 'study'} departs from the paper")
    doc.paragraph(departure_summary(table))
    doc.paragraph(
        "Each row compares one outcome the paper reports (its table named in the outcome or in "
        "bowden.study.paper_values) with this study's: flagged where the direction differs, where the "
        "size differs by more than the tolerance (in the row's unit), or where one finds p < 0.05 and "
        "the other not. Rows marked 'calibrated, not evidence' compare what the simulator was tuned to.",
        "note",
    )
    if table.empty:
        return
    doc.table(family_summary(table), f"Comparisons with the paper per family of outcomes, {kind}", "{:.0f}")
    shown = table[table["departs in"] != ""].set_index(["family", "outcome", "comparison"])
    evidence = shown[shown["evidence"] != CALIBRATED].drop(columns="evidence")
    if not evidence.empty:
        doc.table(evidence, f"Where the {kind} study departs from the paper (evidence)", "{:.3g}")
    if inputs.simulated:
        doc.heading("Calibration", level=3)
        doc.paragraph(
            "These parameters of the simulator were chosen so that it reproduces the named table of the "
            "paper; the outcomes they set are not evidence that the simulation reproduces the paper.",
        )
        doc.table(calibration_table(), "What the simulator was fitted to, and where that is documented")
        calibrated_rows = table[table["evidence"] == CALIBRATED]
        calibrated_rows = calibrated_rows.set_index(["family", "outcome", "comparison"])
        if not calibrated_rows.empty:
            doc.table(
                calibrated_rows,
                f"Calibrated outcomes beside the paper ({kind}; calibrated, not evidence)",
                "{:.3g}",
            )


def questionnaire_section(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """Friedman tests, post-hoc comparisons and the questionnaire figures (left out without answers)."""
    with doc.section("Questionnaires"):
        if not inputs.statistics.questionnaires.empty:
            _questionnaire_tables(doc, inputs, kind)
        if not inputs.questionnaires.empty:
            _questionnaire_figures(doc, inputs, kind)


def _questionnaire_tables(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """The Friedman tests and each Bonferroni post-hoc, with the paper's p where it gives one."""
    tests = inputs.statistics.questionnaires.copy()
    tests["paper p"] = [
        str(paper_values.questionnaire_p(str(q), str(item)) or "–")
        for q, item in zip(tests["questionnaire"], tests["item"], strict=True)
    ]
    doc.table(
        tests.set_index(["questionnaire", "item"]),
        f"Friedman tests across conditions ({kind}); medians per condition; the paper's p where its "
        "Results give one (it publishes no medians as numbers)",
        "{:.3g}",
    )
    reported = paper_values.nordic_pairs()
    for name, table in inputs.statistics.questionnaire_posthoc.items():
        questionnaire, _, item = name.partition("/")
        table = table.copy()
        if questionnaire == QUESTIONNAIRE_NORDIC:
            published = {(str(r["from"]), str(r["to"])): str(r["p"]) for _, r in
                         reported[reported["item"] == item].iterrows()}
            table["paper p"] = [
                published.get((str(a), str(b)), published.get((str(b), str(a)), "–"))
                for a, b in zip(table["group_a"], table["group_b"], strict=True)
            ]
        doc.table(table, f"{name}: Bonferroni post-hoc (MATLAB multcompare); the paper's p where its "
                  "Results give one", "{:.3g}")


def _questionnaire_figures(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """The Nordic body map and the Borg RPE and fatigue box plots."""
    answers, posthoc = inputs.questionnaires, inputs.statistics.questionnaire_posthoc
    doc.figure_later(
        partial(questionnaire_figures.nordic_body_map, title=f"Nordic questionnaire, {kind}"), answers,
        caption="Median discomfort per body site and condition, seen from behind",
        dpi=80,
    )
    for questionnaire, ylabel in ((QUESTIONNAIRE_BORG_RPE, "Borg RPE (6–20)"),
                                  (QUESTIONNAIRE_FATIGUE, "perceived fatigue (1–7)")):
        boxplots = partial(
            questionnaire_figures.questionnaire_boxplots, ylabel=ylabel, title=f"{ylabel}, {kind}"
        )
        doc.figure_later(
            boxplots, answers, questionnaire, posthoc,
            caption=f"{ylabel} per condition, one dot per participant; ** p < 0.001, * p < 0.05 "
            "(Bonferroni post-hoc after a Friedman test with p < 0.05)",
            dpi=80,
        )
