"""The study report: one self-contained HTML file with the paper's tables and figures.

Every table the simulation reproduces stands beside the paper's published numbers; simulated results
are labelled as simulated in the title, a banner and every table caption. A section the study has no
data for is left out; the table of contents lists those shown.
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from datetime import UTC, datetime

import pandas as pd

from bowden import __version__
from bowden.analysis import MethodsText
from bowden.analysis.methods import StatisticsDone, with_statistics
from bowden.analysis.outcomes import IEMG_PREFIX, PERCENT_ERROR_RMSE, TENSION_RMSE, TORQUE_RMSE, StudyOutcomes
from bowden.model import CompensationModel
from bowden.model.transmission import friction_from_slopes
from bowden.stats import effects_table, pairwise_table, significance_html, significance_table
from bowden.stats.analysis import OutcomeAnalysis
from bowden.study import paper_values
from bowden.study.paper_values.iemg import TABLE_LABELS as IEMG_TABLE_LABELS
from bowden.study.report import figures
from bowden.study.report.comparison_sections import departures_section, questionnaire_section
from bowden.study.report.html import FigureSubmit, HtmlDocument
from bowden.study.report.notes import condense_notes
from bowden.study.report.paper_tables import (
    paper_effects_table,
    paper_means,
    paper_pairwise_table,
    paper_significance_html,
)
from bowden.study.report.study_tables import (
    beside,
    condition_comparisons,
    explain_not_compared,
    model_table,
    paper_peak_table,
    peak_table,
    side_by_side,
    tracking_table,
)
from bowden.study.statistics import KINEMATIC_LABELS, MUSCLE_LABELS, StudyStatistics, outcome_data

# Said under every table of pairwise comparisons, whose skipped cells read "N/A (p (C) = 0.231)".
NOT_COMPARED = (
    "; N/A (p (C) = …): not compared, as in the paper, because the factor's Type III test had p ≥ 0.05"
)


@dataclass
class ReportInputs:
    """What the report is made of."""

    outcomes: StudyOutcomes
    statistics: StudyStatistics
    methods: MethodsText  # the analysis; the report adds the identification and the statistics
    model: CompensationModel | None
    simulated: bool
    n_participants: int
    n_trials: int
    identification_figure: object | None = None
    identification_text: str = ""
    timings: dict[str, float] = field(default_factory=dict)
    questionnaires: pd.DataFrame = field(default_factory=pd.DataFrame)  # the long answers table
    trials: pd.DataFrame = field(default_factory=pd.DataFrame)  # bowden.study.trial_list.trial_list


def build_report(inputs: ReportInputs, *, figure_submit: FigureSubmit | None = None) -> HtmlDocument:
    """Assemble the report document; ``figure_submit`` starts each figure on a worker as it is added
    (:class:`~bowden.study.report.html.HtmlDocument`)."""
    kind = "simulated" if inputs.simulated else "measured"
    doc = _front(inputs, kind, figure_submit)
    for section in (_identification_section, _tracking_section, _kinematics_section, _iemg_section,
                    departures_section, questionnaire_section, _closing_sections):
        section(doc, inputs, kind)
    return doc


def _count(n: int, word: str) -> str:
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


def _front(inputs: ReportInputs, kind: str, figure_submit: FigureSubmit | None) -> HtmlDocument:
    """The title, the simulated-data banner and the study's size."""
    title = "bowden study report" + (" — SIMULATED cohort" if inputs.simulated else "")
    doc = HtmlDocument(title, caption_label=kind if inputs.simulated else "", figure_submit=figure_submit)
    if inputs.simulated:
        doc.banner(
            "Simulated data: virtual participants on a simulated suit (bowden.sim). These results "
            "demonstrate the pipeline and the controller's behaviour; they are not human data and must "
            "not be reported as such. The paper's published values are shown beside them for comparison."
        )
    doc.paragraph(
        f"{_count(inputs.n_participants, 'participant')}, {_count(inputs.n_trials, 'trial')}. Generated "
        f"{datetime.now(UTC).strftime('%Y-%m-%d %H:%M UTC')} by bowden {__version__}.",
        "note",
    )
    return doc


def _identification_section(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """The identified lines, the friction factor they imply, the fit and its figure."""
    with doc.section("Transmission identification"):
        if inputs.model is not None:
            doc.table(model_table(inputs.model), f"Identified compensation lines ({kind} bench)", "{:.4g}")
            try:
                k = friction_from_slopes(inputs.model.raising.slope_m, inputs.model.lowering.slope_m)
                doc.paragraph(f"Implied friction factor k = μ·sin(φ/2) = {k:.3f}.")
            except ValueError:
                doc.paragraph("The slopes do not fit one friction factor (raising slope below lowering).")
        if inputs.identification_text:
            doc.raw_table(f"<pre>{html.escape(inputs.identification_text)}</pre>")
        if inputs.identification_figure is not None:
            doc.figure(
                inputs.identification_figure, "Motor torque against load-cell tension, raising and lowering"
            )


def _tracking_tables(inputs: ReportInputs, kind: str) -> list[tuple[pd.DataFrame, str, str]]:
    """(table, caption, number format) of each tracking table the study has data for."""
    tables = []
    for measure, paper, caption, fmt in (
        (TENSION_RMSE, paper_values.tension_rmse_n(), "Tension tracking RMSE (N)", "{:.2f}"),
        (TORQUE_RMSE, paper_values.torque_rmse_nm(), "Shoulder torque tracking RMSE (Nm)", "{:.2f}"),
        (PERCENT_ERROR_RMSE, paper_values.percent_error_rmse(), "RMSE of the percent error (%)", "{:.1f}"),
    ):
        ours = tracking_table(inputs.outcomes, measure)
        if ours is not None:
            tables.append((side_by_side(ours, paper, kind), f"{caption}, {kind} vs the paper", fmt))
    for phase in ("raising", "lowering"):
        ours_peak = peak_table(inputs.outcomes.outcomes, phase)
        if ours_peak is not None:
            both = pd.concat({kind: ours_peak, "paper": paper_peak_table(phase)}, names=["source"])
            tables.append((
                both, f"Peak percent error while {phase}, mean (SD; n = 1 where one repetition), and its "
                f"normalised time, {kind} vs paper", "{:.3g}",
            ))
    return tables


def _tracking_section(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """Tension, torque and percent error against the paper's tables; one participant's curves."""
    tables = _tracking_tables(inputs, kind)
    participants = sorted(set(inputs.outcomes.curves["participant"]))
    with doc.section("Tension and torque tracking"):
        if tables and inputs.simulated:
            doc.paragraph(
                "Calibration: the simulated sheath's friction and drag were chosen so that the simulated "
                "tension errors follow the paper's tension table (docs/simulation.md); the tension, torque "
                "and percent error tables below are therefore not independent evidence, the other outcomes "
                "are.",
                "note",
            )
        elif not tables and participants:
            doc.paragraph("No load-cell data in this study: no tension or torque tracking errors.", "note")
        for table, caption, fmt in tables:
            doc.table(table, caption, fmt)
        if participants:
            doc.figure_later(
                figures.participant_curves, inputs.outcomes.curves, participants[0],
                caption=f"Participant {participants[0]} ({kind}): mean ± SD over the kept repetitions; each "
                "suit condition's desired torque and tension dashed in its colour",
                dpi=80,
            )


def _boxplot_caption(what: str, table: str) -> str:
    return (
        f"{what}, the paper's mean (Table {table}) as a diamond; ** p < 0.001, * p < 0.05 between "
        "conditions, speeds grouped (Holm), where the condition effect has p < 0.05"
    )


def _pairwise(analyses: list[OutcomeAnalysis], factor: str) -> pd.DataFrame:
    """The study's pairwise table, its skipped cells saying why."""
    table = pairwise_table(analyses, factor="condition" if factor == "condition" else "speed")
    return explain_not_compared(table, analyses, factor)


def _kinematics_section(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """Elevation RMSE and SPARC: figures, effects and pairwise comparisons beside the paper."""
    fits = inputs.statistics.kinematics
    by_name = {fit.name: fit for fit in fits}
    with doc.section("Trajectory tracking and smoothness"):
        for measure, label in (("elevation_rmse_rad", "Elevation RMSE (deg)"),
                               ("sparc", "SPARC (sign flipped)")):
            data = outcome_data(inputs.outcomes.outcomes, measure, "entire")
            if not data.empty:
                pairs = condition_comparisons(by_name.get(KINEMATIC_LABELS[measure]))
                doc.figure_later(
                    figures.condition_boxplots, data, label, f"{label}, {kind}", pairs, paper_means(measure),
                    caption=_boxplot_caption(f"{label} per participant", "S4"),
                )
        if not fits:
            return
        doc.table(
            beside(effects_table(fits), paper_effects_table(None), kind),
            f"Elevation RMSE and SPARC, mean (SD) and GLMM p-values, {kind} and the paper (Table S4)",
        )
        doc.table(
            beside(_pairwise(fits, "condition"), paper_pairwise_table("condition", None), kind),
            f"Conditions compared, {kind} and the paper (Table S5: SPARC only){NOT_COMPARED}",
        )
        doc.table(
            beside(_pairwise(fits, "speed"), paper_pairwise_table("speed", None), kind),
            f"Speeds compared, {kind} and the paper (Table S6){NOT_COMPARED.replace('(C)', '(V)')}",
        )


def _iemg_figures(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """Box plots of the anterior and posterior deltoid's iEMG over the entire cycle (the paper's)."""
    entire_fits = {fit.name: fit for fit in inputs.statistics.iemg.get("entire", [])}
    for muscle in ("anterior_deltoid", "posterior_deltoid"):
        data = outcome_data(inputs.outcomes.outcomes, IEMG_PREFIX + muscle, "entire")
        if not data.empty:
            label = muscle.replace("_", " ")
            pairs = condition_comparisons(entire_fits.get(MUSCLE_LABELS[muscle]))
            doc.figure_later(
                figures.condition_boxplots,
                data, "normalised iEMG", f"{label}, {kind}", pairs, paper_means(IEMG_PREFIX + muscle),
                caption=_boxplot_caption(f"Mean normalised iEMG of the {label}", "S7"),
            )


def _iemg_phase(doc: HtmlDocument, fits: list[OutcomeAnalysis], phase: str, kind: str) -> None:
    """One phase's effects, pairwise comparisons and colour table, each beside the paper's."""
    during = "over the entire cycle" if phase == "entire" else f"while {phase}"
    tables = {"entire": ("S7", "S10"), "raising": ("S8", "S11"), "lowering": ("S9", "S12")}[phase]
    doc.table(
        beside(effects_table(fits), paper_effects_table(phase), kind),
        f"iEMG {during}: mean (SD) and GLMM p-values, {kind} and the paper (Table {tables[0]})",
    )
    doc.table(
        beside(_pairwise(fits, "condition"), paper_pairwise_table("condition", phase), kind),
        f"iEMG {during}: conditions compared, {kind} and the paper (Table {tables[1]}){NOT_COMPARED}",
    )
    doc.raw_table(
        significance_html(
            significance_table(fits, factor="condition"),
            caption=f"iEMG change between conditions {during} ({kind}): green decrease, red "
            "increase; ** p < 0.001, * p < 0.05 (Holm), shown where the condition effect has p < 0.05",
        )
    )
    doc.raw_table(
        paper_significance_html(
            phase,
            f"The same in the paper ({IEMG_TABLE_LABELS['colours'][phase]}), beside the {kind} table "
            "above: its colours and significance codes as printed",
        )
    )


def _iemg_section(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """iEMG per phase: figures, effects, pairwise comparisons and the colour tables beside the paper's."""
    with doc.section("Muscle activity (iEMG)"):
        _iemg_figures(doc, inputs, kind)
        for phase in ("entire", "raising", "lowering"):
            fits = inputs.statistics.iemg.get(phase, [])
            if fits:
                _iemg_phase(doc, fits, phase, kind)


def complete_methods(inputs: ReportInputs) -> MethodsText:
    """The analysis' methods followed by the identification and the statistics that were done."""
    statistics = inputs.statistics
    questionnaires = statistics.questionnaires
    done = StatisticsDone(
        kinematic_outcomes=tuple(
            {"RMSE (deg)": "elevation RMSE", "SPARC (-)": "SPARC"}.get(fit.name, fit.name)
            for fit in statistics.kinematics
        ),
        iemg_muscles={phase: len(fits) for phase, fits in statistics.iemg.items()},
        analyses=(*statistics.kinematics, *(fit for fits in statistics.iemg.values() for fit in fits)),
        not_fitted=len(statistics.failures),
        questionnaire_items=0 if questionnaires.empty else int(questionnaires["p"].notna().sum()),
        posthoc_items=len(statistics.questionnaire_posthoc),
    )
    return with_statistics(inputs.methods, model=inputs.model, statistics=done)


def _closing_sections(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """The trials analysed, the methods, the notes and the time per stage."""
    if not inputs.trials.empty:
        doc.heading("Trials")
        doc.table(
            inputs.trials,
            "The trials analysed: how each stopped and the compensation it ran with (the model by the first "
            "12 hex digits of its model.json's SHA-256; each trial's metadata holds the whole hash and the "
            "coefficients)",
        )
    methods = complete_methods(inputs)
    doc.heading("Methods")
    doc.paragraph(methods.paragraph)
    doc.raw_table("<ol>" + "".join(f"<li>{html.escape(ref)}</li>" for ref in methods.references) + "</ol>")
    notes = condense_notes((*inputs.outcomes.info.notes, *inputs.statistics.failures))
    if notes:
        doc.heading("Notes")
        for note in notes:
            doc.paragraph(note, "note")
    if inputs.timings:
        doc.table(pd.DataFrame({"seconds": inputs.timings}).rename_axis("stage"), "Time per stage", "{:.1f}")
