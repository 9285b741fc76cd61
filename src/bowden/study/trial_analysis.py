"""One stored trial's analysis as a task, for :func:`bowden.study.analyze.analyze_store`'s engine.

A worker on this machine reads the trial from the store itself (:class:`StoredTrialTask`: SQLite's
WAL lets readers work beside the writer), so the parent does not read and send every trial; a Dask
worker elsewhere gets the trial's samples and sEMG with the task (:class:`LoadedTrialTask`). Either
way the worker first checks that the trial can be analysed and sends back why not, or its
:class:`~bowden.analysis.TrialOutcomes`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from bowden.analysis import (
    AnalysisParameters,
    SegmentationParameters,
    TrialOutcomes,
    analyse_trial,
    segment_repetitions,
)
from bowden.analysis.outcomes import TrialMetadata
from bowden.errors import RecordingError
from bowden.store.study_store import StudyStore


@dataclass(frozen=True, kw_only=True)
class TrialJob:
    """What every analysis task carries: which trial, its repetition count (or why it has none), settings."""

    metadata: TrialMetadata
    count: int | str | None
    parameters: AnalysisParameters


@dataclass(frozen=True, kw_only=True)
class StoredTrialTask:
    """A trial the worker reads from the store at ``store_path`` (workers on this machine)."""

    job: TrialJob
    store_path: Path
    trial_id: int


@dataclass(frozen=True, kw_only=True)
class LoadedTrialTask:
    """A trial sent with its data (workers that cannot open the store)."""

    job: TrialJob
    samples: pd.DataFrame
    emg: pd.DataFrame | None


def analyse_task(task: StoredTrialTask | LoadedTrialTask) -> TrialOutcomes | str:
    """The trial's outcomes, or why it cannot be analysed (module level, so that workers can run it)."""
    if isinstance(task, StoredTrialTask):
        with StudyStore(task.store_path) as store:
            samples, emg = store.trial_samples(task.trial_id), store.trial_emg(task.trial_id)
    else:
        samples, emg = task.samples, task.emg
    job = task.job
    problem = unusable(samples, job.count, job.parameters.segmentation)
    if problem is not None:
        return problem
    return analyse_trial(job.metadata, samples, emg, job.parameters)


def unusable(samples: Any, count: int | str | None, segmentation: SegmentationParameters) -> str | None:
    """Why a trial cannot be analysed (None if it can): bad count, no data, wrong number of cycles."""
    if isinstance(count, str):
        return count
    # A trial of fewer repetitions than are dropped is first checked for what it holds, so that an
    # empty trial is reported as empty.
    drop = segmentation.drop_first if count is None else min(segmentation.drop_first, count - 1)
    try:
        segment_repetitions(
            samples, dataclasses.replace(segmentation, expected_repetitions=count, drop_first=drop)
        )
    except RecordingError as error:
        return str(error)
    if count is not None and count <= segmentation.drop_first:
        return (
            f"it holds {count} repetition{'s' if count > 1 else ''} and, as the other trials hold more, "
            f"the first {segmentation.drop_first} of each trial is dropped (adaptation): none would be left"
        )
    return None
