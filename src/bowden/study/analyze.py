"""``bowden analyze``: a study store → outcome table, statistics and the report.

The same code serves a real study's store and the simulated one of ``bowden study``. Two keys of
each trial's metadata (the contract every writer follows: ``bowden run``, ``bowden serve`` and the
study pipeline) steer it:

``"repetitions"``
    the number of raise-and-lower cycles the trial's reference held. Each trial is checked against
    its own count; stores written by ``bowden run`` before this key existed keep it under
    ``"reference"`` and are read there; without either, the paper's 10.
``"backend"``
    what the trial ran on: ``contracts.SIMULATED_BACKENDS`` are simulations, anything else (``"can"``,
    or no backend recorded) is measured. The report is called simulated, measured, or — when a store
    holds both — MIXED, and then its results (which pool both kinds) are labelled simulated.

A trial that cannot be analysed (no samples, fewer or more repetitions than it should hold) is
skipped; the report's notes and :attr:`AnalysisReport.skipped` name it and say why. So are trials a
session set aside (stopped early, or redone by the operator, with the reason) and trials left open
(no end recorded: a recording cut off by a killed server). The report lists the participants as
registered and the session plans with their condition order (:mod:`bowden.store.session_facts`).

Conditions and speeds a lab defined itself (``support_70``, ``V4``) are analysed and kept in the
outcome table, described in a section of their own and named in the notes; the paper's comparisons
take the paper's conditions and speeds only (:mod:`bowden.study.report.custom_protocols`).
"""

from __future__ import annotations

import dataclasses
import json
import logging
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final, Literal

import pandas as pd

from bowden.analysis import (
    AnalysisParameters,
    SegmentationParameters,
    StudyOutcomes,
    TrialOutcomes,
    methods_text,
)
from bowden.analysis.outcomes import TrialMetadata, combine_trial_outcomes
from bowden.contracts import REPETITIONS_PER_TRIAL, SIMULATED_BACKENDS
from bowden.engine.pool import Engine, Pending, pool_size, study_engine
from bowden.errors import ModelFileError, ParameterError, RecordingError, StoreError
from bowden.identify import TransmissionIdentifier, plot_identification
from bowden.model import CompensationModel
from bowden.model.model_file import model_from_dict
from bowden.store.session_facts import SessionFacts, left_open_notes, session_facts
from bowden.store.study_store import StoredTrial, StudyStore
from bowden.study.emg.stored import emg_imports, trials_with_emg
from bowden.study.progress import StageProgress
from bowden.study.report.build import ReportInputs, build_report
from bowden.study.report.custom_protocols import (
    custom_definitions,
    custom_notes,
    custom_section,
    custom_table,
    is_paper,
    paper_part,
)
from bowden.study.report.html import FigureJob, FigureMapper, HtmlDocument
from bowden.study.statistics import FitJob, FitMapper, FitResult, StudyStatistics, study_statistics
from bowden.study.trial_analysis import LoadedTrialTask, StoredTrialTask, TrialJob, analyse_task
from bowden.study.trial_list import id_ranges, trial_list

_log = logging.getLogger(__name__)

# Keys of a trial's metadata that the analysis reads (see the module docstring).
REPETITIONS_KEY: Final = "repetitions"
BACKEND_KEY: Final = "backend"
# Where `bowden run` kept the repetition count before REPETITIONS_KEY was agreed.
_LEGACY_REFERENCE_KEY: Final = "reference"

DataKind = Literal["measured", "simulated", "mixed"]


@dataclass
class AnalysisReport:
    """What ``analyze_store`` produced.

    ``n_trials`` counts the trials analysed; ``skipped`` has one line per completed trial left out
    (which one and why); ``data_kind`` is what the report calls the analysed trials.
    """

    report: Path
    outcomes: StudyOutcomes
    statistics: StudyStatistics
    n_trials: int
    skipped: tuple[str, ...] = ()
    data_kind: DataKind = "measured"
    participants: pd.DataFrame | None = None  # the registry (bowden.store.session_facts)
    plans: pd.DataFrame | None = None  # the session plans, with their condition order


def analyze_store(
    store_path: str | Path,
    report_path: str | Path,
    *,
    simulated: bool | None = None,
    bench_path: str | Path | None = None,
    progress: StageProgress | None = None,
    timings: dict[str, float] | None = None,
    repetitions: int | None = None,
    workers: int | None = None,
    engine: Engine | None = None,
    appendix: Callable[[HtmlDocument], object] | None = None,
) -> AnalysisReport:
    """Analyse every completed trial of a store, fit the statistics, write the report.

    ``simulated`` labels the report; None reads it from each trial's metadata (``"backend"``): all
    simulated → simulated, none → measured, both → MIXED (see the module docstring).
    ``bench_path`` (a bench recording) adds the identification figure. ``repetitions`` is the number
    of cycles every trial must hold; None takes each trial's own from its metadata, else the paper's 10.
    The first repetition of each trial is dropped (adaptation) unless no trial holds more than one.
    ``workers`` trials are analysed at a time (None: one per CPU core, but one per ten trials at most,
    :func:`bowden.engine.pool.pool_size`; 1: in this process), or the
    trials and the statistics' models are tasks on ``engine`` (``bowden study``'s worker pool or its
    Dask cluster); results depend on neither.
    ``appendix`` adds sections of its own at the end of the report (``bowden study --compensation``).

    Raises
    ------
    StoreError
        No store at ``store_path``, no completed trial in it, or none that can be analysed.
    """
    store_path = Path(store_path)
    if not store_path.exists():
        raise StoreError(f"no study store at {store_path}")
    progress = progress if progress is not None else StageProgress(enabled=False)
    with StudyStore(store_path) as store, ExitStack() as stack:
        facts = session_facts(store)
        skipped = list(left_open_notes(facts))
        trials = store.completed_trials()
        if not trials:
            raise StoreError(f"{store_path} holds no completed trial to analyse" + (
                f" ({'; '.join(skipped)})" if skipped else ""))
        # Each trial's analysis is a task on the engine (worker processes, or Dask), and so is each
        # statistical model; results come back in task order, so none depends on the workers.
        if engine is None:  # a pool only where its start pays: not for a handful of trials
            engine = stack.enter_context(study_engine(pool_size(len(trials), workers)))
        identification = None if bench_path is None else engine.submit(fit_identification, Path(bench_path))
        analysed = _analyse_trials(store, trials, facts, repetitions, engine, progress, skipped)
        outcomes, answers, beyond = _outcomes_and_notes(store, store_path, analysed, skipped)
        with progress.spinner("fitting the statistics"):
            statistics = study_statistics(outcomes.outcomes, answers, mapper=_fit_mapper(engine))
        given: DataKind = "simulated" if simulated else "measured"
        kind = data_kind(analysed.kept.values()) if simulated is None else given
        inputs = _report_inputs(store, analysed, outcomes, statistics, answers, identification, kind, timings)
        with progress.spinner("writing the report"):
            document = build_report(inputs, figure_submit=engine.submit)  # drawn while it is built
            if kind == "mixed":
                _label_mixed(document, analysed.kept)
            custom_section(document, beyond)
            _session_sections(document, facts)
            if appendix is not None:
                appendix(document)
            document.draw_figures(_figure_mapper(engine))  # collect them
            report = document.write(report_path)
    return AnalysisReport(
        report=report,
        outcomes=outcomes,
        statistics=statistics,
        n_trials=outcomes.info.n_trials,
        skipped=tuple(skipped),
        data_kind=kind,
        participants=facts.participants,
        plans=facts.plans,
    )


def _report_inputs(
    store: StudyStore, analysed: _Analysed, outcomes: StudyOutcomes, statistics: StudyStatistics,
    answers: pd.DataFrame, identification: Pending[tuple[Any, dict[str, Any], str]] | None, kind: DataKind,
    timings: dict[str, float] | None,
) -> ReportInputs:
    figure, text = _identification_figure(identification)
    return ReportInputs(
        outcomes=outcomes,
        statistics=statistics,
        methods=methods_text(info=outcomes.info),
        model=_stored_model(store),
        # Results that pool measured and simulated trials are not measured results.
        simulated=kind != "measured",
        n_participants=outcomes.info.n_participants,
        n_trials=outcomes.info.n_trials,
        identification_figure=figure,
        identification_text=text,
        timings=dict(timings or {}),
        questionnaires=answers,
        trials=trial_list(_trial_rows(store, analysed.kept)),
    )


@dataclass
class _Analysed:
    """The trials' outcomes, the metadata of the trials they came from, and how they were analysed."""

    results: list[TrialOutcomes]
    kept: dict[int, dict[str, Any]]  # trial id → metadata of the trials analysed
    parameters: AnalysisParameters


def _analyse_trials(
    store: StudyStore, trials: list[StoredTrial], facts: SessionFacts, repetitions: int | None,
    engine: Engine, progress: StageProgress, skipped: list[str],
) -> _Analysed:
    """Each trial's outcomes; the trials set aside or that cannot be analysed go to ``skipped``."""
    metadata = {trial.trial_id: store.trial_metadata(trial.trial_id) for trial in trials}
    counts = {trial_id: _expected(meta, repetitions) for trial_id, meta in metadata.items()}
    # The paper drops each trial's first repetition (adaptation); a study whose trials hold one
    # repetition each keeps it, and the methods text says so. One rule for every trial.
    drop_first = 0 if all(n == 1 or isinstance(n, str) for n in counts.values()) else 1
    parameters = AnalysisParameters(
        segmentation=SegmentationParameters(expected_repetitions=None, drop_first=drop_first)
    )
    jobs = _analysis_jobs(store, trials, facts.set_aside, counts, parameters, engine.shares_files)
    analysed = _Analysed([], {}, parameters)
    with progress.bar("analysing trials", len(trials)) as advance:
        for done, (trial, result) in enumerate(zip(trials, engine.map(_analyse_job, jobs), strict=True), 1):
            set_aside = facts.set_aside.get(trial.trial_id)
            if set_aside is not None:
                skipped.append(f"{_describe(trial)} set aside: {set_aside}")
            elif isinstance(result, str):
                skipped.append(f"{_describe(trial)} skipped: {result}")
                _log.warning("bowden analyze: %s", skipped[-1])
            elif result is not None:
                analysed.kept[trial.trial_id] = metadata[trial.trial_id]
                analysed.results.append(result)
            advance(done)
    return analysed


def _outcomes_and_notes(
    store: StudyStore, store_path: Path, analysed: _Analysed, skipped: list[str]
) -> tuple[StudyOutcomes, pd.DataFrame, Any]:
    """The study's outcomes (stored, every trial's) with the report's notes, the questionnaire answers,
    and the table of the lab's own conditions and speeds; both of the first restricted to the paper's
    when the lab defined its own."""
    outcomes = _combine(analysed.results, analysed.parameters, store_path, analysed.kept, skipped)
    # The report's notes say which trials are missing and why, where each trial's EMG came from, and
    # which conditions and speeds are the lab's own (out of the paper's comparisons).
    definitions = custom_definitions(store)
    extra = custom_notes(outcomes.outcomes, definitions)
    notes = (*skipped, *emg_sources(store, analysed.kept), *extra, *outcomes.info.notes)
    outcomes = dataclasses.replace(outcomes, info=dataclasses.replace(outcomes.info, notes=notes))
    store.replace_outcomes(outcomes.outcomes)  # every trial's, the custom ones too
    answers = store.questionnaires()
    beyond = custom_table(outcomes.outcomes, answers, definitions)
    if extra:
        outcomes = paper_part(outcomes)
        answers = answers[is_paper(answers)] if not answers.empty else answers
    return outcomes, answers, beyond


def expected_repetitions(metadata: Mapping[str, Any]) -> int | None:
    """The repetitions a trial's reference held, from its metadata; None: any number (a free run).

    Reads ``metadata["repetitions"]`` (``null`` there means the wearer followed no reference, as on
    the real suit without a display), else ``metadata["reference"]["repetitions"]`` (``bowden run``
    before the key was agreed), else the paper's 10 (``contracts.REPETITIONS_PER_TRIAL``).

    Raises
    ------
    RecordingError
        If the value is not a positive whole number.
    """
    if REPETITIONS_KEY in metadata:
        value: object = metadata[REPETITIONS_KEY]
        if value is None:
            return None
    else:
        reference = metadata.get(_LEGACY_REFERENCE_KEY)
        value = reference.get(REPETITIONS_KEY) if isinstance(reference, Mapping) else None
        if value is None:
            return REPETITIONS_PER_TRIAL
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise RecordingError(f"its metadata gives {value!r} repetitions, not a positive whole number")
    return value


def _expected(metadata: Mapping[str, Any], override: int | None) -> int | str | None:
    """The trial's repetition count (``override`` if given), or why it cannot be known."""
    if override is not None:
        return override
    try:
        return expected_repetitions(metadata)
    except RecordingError as error:
        return str(error)


AnalysisJob = StoredTrialTask | LoadedTrialTask | None


def _analysis_jobs(
    store: StudyStore,
    trials: list[StoredTrial],
    set_aside: Mapping[int, str],
    counts: Mapping[int, int | str | None],
    parameters: AnalysisParameters,
    shares_files: bool,
) -> Iterator[AnalysisJob]:
    """One job per trial, in trial order (None: set aside, not analysed).

    Workers that can open the store read their trial themselves; others get it sent.
    """
    for trial in trials:
        if trial.trial_id in set_aside:
            yield None
            continue
        which = TrialMetadata(participant=trial.participant, condition=trial.condition, speed=trial.speed)
        job = TrialJob(metadata=which, count=counts[trial.trial_id], parameters=parameters)
        if shares_files:
            yield StoredTrialTask(job=job, store_path=store.path.resolve(), trial_id=trial.trial_id)
        else:
            samples, emg = store.trial_samples(trial.trial_id), store.trial_emg(trial.trial_id)
            yield LoadedTrialTask(job=job, samples=samples, emg=emg)


def _analyse_job(job: AnalysisJob) -> TrialOutcomes | str | None:
    return None if job is None else analyse_task(job)


def _combine(
    results: list[TrialOutcomes],
    parameters: AnalysisParameters,
    store_path: Path,
    kept: Mapping[int, object],
    skipped: list[str],
) -> StudyOutcomes:
    try:
        return combine_trial_outcomes(results, parameters, list(kept))  # each row names its trial
    except ParameterError:
        if kept or not skipped:
            raise
        raise StoreError(
            f"{store_path} holds no trial that can be analysed: " + "; ".join(skipped)
        ) from None


def _figure_mapper(engine: Engine) -> FigureMapper:
    def mapper(function: Callable[[FigureJob], bytes], jobs: Iterable[FigureJob]) -> Iterator[bytes]:
        return engine.map(function, jobs)

    return mapper


def _fit_mapper(engine: Engine) -> FitMapper:
    def mapper(function: Callable[[FitJob], FitResult], jobs: Iterable[FitJob]) -> Iterator[FitResult]:
        return engine.map(function, jobs)

    return mapper


def fit_identification(bench_path: Path) -> tuple[Any, dict[str, Any], str]:
    """The bench's steady-state selection, both robust fits and the summary (a task for the engine)."""
    identifier = TransmissionIdentifier().fit(bench_path)
    fits = {"raising": identifier.raising_fit_, "lowering": identifier.lowering_fit_}
    return identifier.selection_, fits, identifier.summary_.format()


def _identification_figure(pending: Pending[tuple[Any, dict[str, Any], str]] | None) -> tuple[Any, str]:
    if pending is None:
        return None, ""
    selection, fits, text = pending.result()
    return plot_identification(selection, fits), text


def _trial_rows(store: StudyStore, trial_ids: Iterable[int]) -> pd.DataFrame:
    """The ``trials`` rows of ``trial_ids`` that the report's trial list reads."""
    rows = store.trial_table()
    return rows[rows["id"].isin(list(trial_ids))]


def _describe(trial: StoredTrial) -> str:
    return f"trial {trial.trial_id} (participant {trial.participant}, {trial.condition}, {trial.speed})"


def _is_simulated(metadata: Mapping[str, Any]) -> bool:
    """Whether a trial ran on a simulated suit (its metadata's backend; older stores say "simulation")."""
    return metadata.get(BACKEND_KEY) in SIMULATED_BACKENDS


def data_kind(trials_metadata: Iterable[Mapping[str, Any]]) -> DataKind:
    """What the trials are: all simulated, all measured (no backend recorded counts as measured), or mixed."""
    flags = {_is_simulated(metadata) for metadata in trials_metadata}
    if flags == {True}:
        return "simulated"
    if flags == {True, False}:
        return "mixed"
    return "measured"


def _label_mixed(document: HtmlDocument, trials: Mapping[int, Mapping[str, Any]]) -> None:
    """Title and first banner of a report whose results pool measured and simulated trials."""
    simulated = sorted(i for i, meta in trials.items() if _is_simulated(meta))
    measured = sorted(i for i in trials if i not in simulated)
    document.title = (
        f"bowden study report — MIXED: {len(measured)} measured and {len(simulated)} simulated trials"
    )
    banner = HtmlDocument(title="")
    banner.banner(
        f"Mixed data: this store holds measured trials ({id_ranges(measured)}) and simulated trials "
        f"({id_ranges(simulated)}). Every table, figure and test below pools both kinds, so none of it "
        "is a measured result; the captions call it simulated. Analyse the measured trials in a store "
        "of their own to report them."
    )
    document.parts[:0] = banner.parts


def _session_sections(document: HtmlDocument, facts: SessionFacts) -> None:
    """The participants as registered and the session plans (condition order, seed), when recorded."""
    if facts.participants.empty and facts.plans.empty:
        return
    document.heading("Participants and session plans")
    if not facts.participants.empty:
        document.table(facts.participants, "Participants as registered (pseudonymous ids)", "{:.4g}")
    if not facts.plans.empty:
        document.table(
            facts.plans, "Session plans: condition order (no suit first), seed and progress", "{:.0f}"
        )


def emg_sources(store: StudyStore, trial_ids: Iterable[int]) -> list[str]:
    """One note per EMG source of the analysed trials: an imported file, the trial itself, or none."""
    imports, stored = emg_imports(store), trials_with_emg(store)
    by_source: dict[str, list[int]] = {}
    for trial_id in sorted(trial_ids):
        if trial_id in imports:
            meta = imports[trial_id]
            source = (
                f"imported from {meta.get('file', '?')} (synchronised by {meta.get('via', '?')}: drift "
                f"{meta.get('drift_ppm', float('nan')):+.1f} ppm, largest residual "
                f"{1e3 * meta.get('max_residual_s', float('nan')):.3f} ms)"
            )
        elif trial_id in stored:
            source = "recorded with the trial"
        else:
            source = "none"
        by_source.setdefault(source, []).append(trial_id)
    plural = {True: "trials", False: "trial"}
    return [f"EMG of {plural[len(ids) > 1]} {_ids(ids)}: {source}" for source, ids in by_source.items()]


def _ids(ids: list[int]) -> str:
    return ", ".join(str(i) for i in ids)


def _stored_model(store: StudyStore) -> CompensationModel | None:
    text = store.artifact("model.json")
    if text is None:
        return None
    try:
        return model_from_dict(json.loads(text), source="model.json in the study store")
    except (ValueError, ModelFileError):
        return None
