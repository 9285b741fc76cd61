"""The study report: one self-contained HTML file with the paper's tables and figures.

Every table the simulation reproduces stands beside the paper's published numbers; simulated results
are labelled as simulated in the title, a banner and every table caption.
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, field
from datetime import UTC, datetime
from functools import partial

import pandas as pd

from bowden import __version__
from bowden.analysis import MethodsText
from bowden.analysis.outcomes import (
    IEMG_PREFIX,
    PEAK_PERCENT_ERROR,
    PEAK_PERCENT_ERROR_TIME,
    PERCENT_ERROR_RMSE,
    TENSION_RMSE,
    TORQUE_RMSE,
    StudyOutcomes,
)
from bowden.contracts import (
    CONDITION_LABELS,
    CONDITIONS,
    QUESTIONNAIRE_BORG_RPE,
    QUESTIONNAIRE_FATIGUE,
    QUESTIONNAIRE_NORDIC,
    SPEEDS,
)
from bowden.model import CompensationModel
from bowden.model.transmission import friction_from_slopes
from bowden.stats import effects_table, pairwise_table, significance_html, significance_table
from bowden.stats.analysis import OutcomeAnalysis
from bowden.study import paper_values
from bowden.study.departures.calibration import CALIBRATED, calibration_table
from bowden.study.departures.table import all_departures, departure_summary, family_summary
from bowden.study.paper_values.iemg import TABLE_LABELS as IEMG_TABLE_LABELS
from bowden.study.report import figures, questionnaire_figures
from bowden.study.report.html import FigureSubmit, HtmlDocument
from bowden.study.report.paper_tables import (
    paper_effects_table,
    paper_means,
    paper_pairwise_table,
    paper_significance_html,
)
from bowden.study.statistics import KINEMATIC_LABELS, MUSCLE_LABELS, StudyStatistics, outcome_data


@dataclass
class ReportInputs:
    """What the report is made of."""

    outcomes: StudyOutcomes
    statistics: StudyStatistics
    methods: MethodsText
    model: CompensationModel | None
    simulated: bool
    n_participants: int
    n_trials: int
    identification_figure: object | None = None
    identification_text: str = ""
    timings: dict[str, float] = field(default_factory=dict)
    questionnaires: pd.DataFrame = field(default_factory=pd.DataFrame)  # the long answers table
    trials: pd.DataFrame = field(default_factory=pd.DataFrame)  # bowden.study.trial_list.trial_list


def _tracking_table(outcomes: StudyOutcomes, measure: str) -> pd.DataFrame | None:
    data = outcomes.outcomes
    if data[data["measure"] == measure].empty:
        return None
    table = outcomes.rmse_table(measure)
    return table.drop(index=[c for c in table.index if c == "no_suit"], errors="ignore")


def _side_by_side(ours: pd.DataFrame, paper: pd.DataFrame, label: str) -> pd.DataFrame:
    combined = pd.concat({label: ours, "paper": paper.reindex(columns=ours.columns)}, names=["source"])
    return combined.rename(index=CONDITION_LABELS, level="condition")


def _beside(ours: pd.DataFrame, paper: pd.DataFrame, label: str) -> pd.DataFrame:
    """The study's table over the paper's, outcome by outcome, with a source level (study/paper)."""
    both = pd.concat({label: ours, "paper": paper.reindex(columns=ours.columns)}, names=["source"])
    outcomes = list(dict.fromkeys(ours.index.get_level_values(0)))
    order = sorted(range(len(both)), key=lambda i: (
        outcomes.index(both.index[i][1]) if both.index[i][1] in outcomes else len(outcomes),
        both.index[i][0] != label,
    ))
    return both.iloc[order].reorder_levels([1, 0, *range(2, both.index.nlevels)])


def _peak_table(outcomes: pd.DataFrame, phase: str) -> pd.DataFrame | None:
    """Mean (SD) over participants and repetitions of the peak percent error and its time, per speed."""
    rows = {}
    for condition in CONDITIONS[1:]:
        cells = {}
        for speed in SPEEDS:
            for measure, name in (
                (PEAK_PERCENT_ERROR, "peak error (%)"),
                (PEAK_PERCENT_ERROR_TIME, "time (%)"),
            ):
                values = outcomes[
                    (outcomes["measure"] == measure)
                    & (outcomes["phase"] == phase)
                    & (outcomes["condition"] == condition)
                    & (outcomes["speed"] == speed)
                ]["value"].dropna()
                cells[(speed, name)] = (
                    f"{values.mean():.1f} ({values.std(ddof=1):.1f})" if len(values) > 1 else "–"
                )
        rows[CONDITION_LABELS[condition]] = cells
    table = pd.DataFrame.from_dict(rows, orient="index")
    if (table == "–").all().all():
        return None
    table.columns = pd.MultiIndex.from_tuples(
        [tuple(col) for col in table.columns], names=["speed", "quantity"]
    )
    return table


def _paper_peak_table(phase: str) -> pd.DataFrame:
    paper = paper_values.peak_percent_error(phase)
    rows = {}
    for condition in paper.index:
        cells = {}
        for speed in SPEEDS:
            p = paper.loc[condition, speed]
            cells[(speed, "peak error (%)")] = f"{p['peak_error_pct']:.1f} ({p['peak_error_sd']:.1f})"
            cells[(speed, "time (%)")] = f"{p['normalised_time_pct']:.1f} ({p['normalised_time_sd']:.1f})"
        rows[CONDITION_LABELS[condition]] = cells
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.columns = pd.MultiIndex.from_tuples(
        [tuple(col) for col in table.columns], names=["speed", "quantity"]
    )
    return table


def _model_table(model: CompensationModel) -> pd.DataFrame:
    rows = []
    for name, line, fit in (
        ("raising", model.raising, model.raising_fit),
        ("lowering", model.lowering, model.lowering_fit),
    ):
        rows.append(
            {
                "line": name,
                "intercept (Nm)": line.intercept_nm,
                "slope (mm)": 1000.0 * line.slope_m,
                "R² (fitlm robust)": fit.r_squared_robust if fit else math.nan,
                "R² (OLS, corr²)": fit.r_squared_ols if fit else math.nan,
                "n": fit.n if fit else math.nan,
            }
        )
    return pd.DataFrame(rows).set_index("line")


def _condition_comparisons(analysis: OutcomeAnalysis | None) -> list[tuple[str, str, float]]:
    """(condition, condition, Holm p) over the speeds grouped, where the condition effect has p < 0.05."""
    if analysis is None:
        return []
    condition_p = analysis.tests["p"].astype(float).get("condition", float("nan"))
    if not condition_p < 0.05:
        return []
    pairs = analysis.condition_pairs
    return [
        (str(a), str(b), float(p))
        for a, b, p in zip(pairs["level_a"], pairs["level_b"], pairs["p_holm"], strict=True)
    ]


def _departures_section(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
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


def build_report(inputs: ReportInputs, *, figure_submit: FigureSubmit | None = None) -> HtmlDocument:
    """Assemble the report document; ``figure_submit`` starts each figure on a worker as it is added
    (:class:`~bowden.study.report.html.HtmlDocument`)."""
    kind = "simulated" if inputs.simulated else "measured"
    doc = _front(inputs, kind, figure_submit)
    for section in (_identification_section, _tracking_section, _kinematics_section, _iemg_section,
                    _departures_section, _questionnaire_section, _closing_sections):
        section(doc, inputs, kind)
    return doc


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
        f"{inputs.n_participants} participants, {inputs.n_trials} trials. Generated "
        f"{datetime.now(UTC).strftime('%Y-%m-%d %H:%M UTC')} by bowden {__version__}.",
        "note",
    )
    return doc


def _identification_section(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """The identified lines, the friction factor they imply, the fit and its figure."""
    doc.heading("Transmission identification")
    if inputs.model is not None:
        doc.table(_model_table(inputs.model), f"Identified compensation lines ({kind} bench)", "{:.4g}")
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


def _tracking_section(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """Tension, torque and percent error against the paper's tables; one participant's curves."""
    outcomes = inputs.outcomes.outcomes
    doc.heading("Tension and torque tracking")
    if inputs.simulated:
        doc.paragraph(
            "Calibration: the simulated sheath's friction and drag were chosen so that the simulated tension "
            "errors follow the paper's tension table (docs/simulation.md); the tension, torque and percent "
            "error tables below are therefore not independent evidence, the other outcomes are.",
            "note",
        )
    for measure, paper, caption, fmt in (
        (TENSION_RMSE, paper_values.tension_rmse_n(), "Tension tracking RMSE (N)", "{:.2f}"),
        (TORQUE_RMSE, paper_values.torque_rmse_nm(), "Shoulder torque tracking RMSE (Nm)", "{:.2f}"),
        (PERCENT_ERROR_RMSE, paper_values.percent_error_rmse(), "RMSE of the percent error (%)", "{:.1f}"),
    ):
        ours = _tracking_table(inputs.outcomes, measure)
        if ours is None:
            doc.paragraph(f"{caption}: no load-cell data in this study.")
            continue
        doc.table(_side_by_side(ours, paper, kind), f"{caption}, {kind} vs the paper", fmt)
    for phase in ("raising", "lowering"):
        ours_peak = _peak_table(outcomes, phase)
        if ours_peak is not None:
            both = pd.concat({kind: ours_peak, "paper": _paper_peak_table(phase)}, names=["source"])
            doc.table(
                both, f"Peak percent error while {phase}, mean (SD), and its normalised time, {kind} vs paper"
            )

    participants = sorted(set(inputs.outcomes.curves["participant"]))
    if participants:
        doc.figure_later(
            figures.participant_curves, inputs.outcomes.curves, participants[0],
            caption=f"Participant {participants[0]} ({kind}): mean ± SD over the kept repetitions",
            dpi=80,
        )


def _kinematics_section(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """Elevation RMSE and SPARC: figures, effects and pairwise comparisons beside the paper."""
    outcomes = inputs.outcomes.outcomes
    doc.heading("Trajectory tracking and smoothness")
    kinematic_fits = {fit.name: fit for fit in inputs.statistics.kinematics}
    for measure, label in (("elevation_rmse_rad", "Elevation RMSE (deg)"), ("sparc", "SPARC (sign flipped)")):
        data = outcome_data(outcomes, measure, "entire")
        if not data.empty:
            pairs = _condition_comparisons(kinematic_fits.get(KINEMATIC_LABELS[measure]))
            doc.figure_later(
                figures.condition_boxplots, data, label, f"{label}, {kind}", pairs, paper_means(measure),
                caption=f"{label} per participant, the paper's mean (Table S4) as a diamond; ** p < 0.001, "
                "* p < 0.05 between conditions, speeds grouped (Holm), where the condition effect has "
                "p < 0.05",
            )
    if inputs.statistics.kinematics:
        doc.table(
            _beside(effects_table(inputs.statistics.kinematics), paper_effects_table(None), kind),
            f"Elevation RMSE and SPARC, mean (SD) and GLMM p-values, {kind} and the paper (Table S4)",
        )
        doc.table(
            _beside(pairwise_table(inputs.statistics.kinematics, factor="condition"),
                    paper_pairwise_table("condition", None), kind),
            f"Conditions compared, {kind} and the paper (Table S5: SPARC only)",
        )
        doc.table(
            _beside(pairwise_table(inputs.statistics.kinematics, factor="speed"),
                    paper_pairwise_table("speed", None), kind),
            f"Speeds compared, {kind} and the paper (Table S6)",
        )


def _iemg_section(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """iEMG per phase: figures, effects, pairwise comparisons and the colour tables beside the paper's."""
    outcomes = inputs.outcomes.outcomes
    doc.heading("Muscle activity (iEMG)")
    entire_fits = {fit.name: fit for fit in inputs.statistics.iemg.get("entire", [])}
    for muscle in ("anterior_deltoid", "posterior_deltoid"):
        data = outcome_data(outcomes, IEMG_PREFIX + muscle, "entire")
        if not data.empty:
            label = muscle.replace("_", " ")
            pairs = _condition_comparisons(entire_fits.get(MUSCLE_LABELS[muscle]))
            doc.figure_later(
                figures.condition_boxplots,
                data, "normalised iEMG", f"{label}, {kind}", pairs, paper_means(IEMG_PREFIX + muscle),
                caption=f"Mean normalised iEMG of the {label}, the paper's mean (Table S7) as a diamond; "
                "** p < 0.001, * p < 0.05 between conditions, speeds grouped (Holm), where the condition "
                "effect has p < 0.05",
            )
    for phase in ("entire", "raising", "lowering"):
        fits = inputs.statistics.iemg.get(phase, [])
        if not fits:
            continue
        during = "over the entire cycle" if phase == "entire" else f"while {phase}"
        tables = {"entire": ("S7", "S10"), "raising": ("S8", "S11"), "lowering": ("S9", "S12")}[phase]
        doc.table(
            _beside(effects_table(fits), paper_effects_table(phase), kind),
            f"iEMG {during}: mean (SD) and GLMM p-values, {kind} and the paper (Table {tables[0]})",
        )
        doc.table(
            _beside(pairwise_table(fits, factor="condition"), paper_pairwise_table("condition", phase), kind),
            f"iEMG {during}: conditions compared, {kind} and the paper (Table {tables[1]})",
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


def _questionnaire_section(doc: HtmlDocument, inputs: ReportInputs, kind: str) -> None:
    """Friedman tests, post-hoc comparisons and the questionnaire figures."""
    doc.heading("Questionnaires")
    if inputs.statistics.questionnaires.empty:
        doc.paragraph("No questionnaire answers in this study.")
    else:
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
    if not inputs.questionnaires.empty:
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

    doc.heading("Methods")
    doc.paragraph(inputs.methods.paragraph)
    doc.raw_table(
        "<ol>" + "".join(f"<li>{html.escape(ref)}</li>" for ref in inputs.methods.references) + "</ol>"
    )
    if inputs.statistics.failures or inputs.outcomes.info.notes:
        doc.heading("Notes")
        for note in (*inputs.outcomes.info.notes, *inputs.statistics.failures):
            doc.paragraph(note, "note")
    if inputs.timings:
        doc.table(pd.DataFrame({"seconds": inputs.timings}).rename_axis("stage"), "Time per stage", "{:.1f}")
