"""``bowden analyze``: a study store → outcome table, statistics and the report.

The same code serves a real study's store and the simulated one of ``bowden study``.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bowden.analysis import (
    AnalysisParameters,
    SegmentationParameters,
    StudyOutcomes,
    analyse_study,
    methods_text,
)
from bowden.analysis.outcomes import TrialMetadata
from bowden.contracts import REPETITIONS_PER_TRIAL
from bowden.errors import ModelFileError, StoreError
from bowden.identify import TransmissionIdentifier, plot_identification
from bowden.model import CompensationModel
from bowden.model.model_file import model_from_dict
from bowden.study.progress import StageProgress
from bowden.study.report import ReportInputs, write_report
from bowden.study.statistics import StudyStatistics, study_statistics
from bowden.study.store import StudyStore


@dataclass
class AnalysisReport:
    """What ``analyze_store`` produced."""

    report: Path
    outcomes: StudyOutcomes
    statistics: StudyStatistics
    n_trials: int


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
) -> AnalysisReport:
    """Analyse every completed trial of a store, fit the statistics, write the report.

    ``simulated`` labels the report; None reads it from the trials' metadata (backend).
    ``bench_path`` (a bench recording) adds the identification figure. ``repetitions`` is the number
    of cycles a trial must hold; None takes it from the trials' metadata, else the paper's 10.
    ``workers`` trials are analysed at a time (None: one per CPU core); results do not depend on it.
    """
    store_path = Path(store_path)
    if not store_path.exists():
        raise StoreError(f"no study store at {store_path}")
    progress = progress if progress is not None else StageProgress(enabled=False)
    with StudyStore(store_path) as store:
        trials = store.completed_trials()
        if not trials:
            raise StoreError(f"{store_path} holds no completed trial to analyse")
        if simulated is None:
            simulated = _is_simulated(store)
        n_participants = len({t.participant for t in trials})
        if repetitions is None:
            repetitions = int(
                store.trial_metadata(trials[0].trial_id).get("repetitions", REPETITIONS_PER_TRIAL)
            )
        # The paper drops each trial's first repetition (adaptation); a one-repetition trial keeps it,
        # and the methods text says so.
        segmentation = SegmentationParameters(
            expected_repetitions=repetitions, drop_first=min(1, repetitions - 1)
        )
        parameters = AnalysisParameters(segmentation=segmentation)

        def items() -> Iterator[tuple[TrialMetadata, Any, Any]]:
            with progress.bar("analysing trials", len(trials)) as advance:
                for done, (trial, samples, emg) in enumerate(store.iter_trials(), start=1):
                    meta = TrialMetadata(
                        participant=trial.participant, condition=trial.condition, speed=trial.speed
                    )
                    yield meta, samples, emg
                    advance(done)

        outcomes = analyse_study(items(), parameters, workers=workers or os.cpu_count() or 1)
        store.replace_outcomes(outcomes.outcomes)
        with progress.spinner("fitting the statistics"):
            statistics = study_statistics(outcomes.outcomes, store.questionnaires())
        model = _stored_model(store)

    figure, text = None, ""
    if bench_path is not None:
        identifier = TransmissionIdentifier().fit(bench_path)
        figure = plot_identification(
            identifier.selection_, {"raising": identifier.raising_fit_, "lowering": identifier.lowering_fit_}
        )
        text = identifier.summary_.format()
    inputs = ReportInputs(
        outcomes=outcomes,
        statistics=statistics,
        methods=methods_text(info=outcomes.info),
        model=model,
        simulated=simulated,
        n_participants=n_participants,
        n_trials=len(trials),
        identification_figure=figure,
        identification_text=text,
        timings=dict(timings or {}),
    )
    with progress.spinner("writing the report"):
        report = write_report(inputs, report_path)
    return AnalysisReport(report=report, outcomes=outcomes, statistics=statistics, n_trials=len(trials))


def _is_simulated(store: StudyStore) -> bool:
    trials = store.completed_trials()
    return bool(trials) and store.trial_metadata(trials[0].trial_id).get("backend") == "simulation"


def _stored_model(store: StudyStore) -> CompensationModel | None:
    text = store.artifact("model.json")
    if text is None:
        return None
    try:
        return model_from_dict(json.loads(text), source="model.json in the study store")
    except (ValueError, ModelFileError):
        return None
