"""Transmission identification: bench recordings -> :class:`bowden.model.CompensationModel`.

The paper's friction identification ("Model identification") as a tool: read and validate bench
recordings, low-pass and select steady-state samples, fit one robust line per direction with
:func:`robustfit` (equal to MATLAB's), and wrap it all in the scikit-learn style
:class:`TransmissionIdentifier`.

>>> from bowden.identify import robustfit
>>> fit = robustfit([1, 2, 3, 4, 5, 6, 7, 8, 9, 10], [3.1, 5.2, 6.9, 9.1, 11, 12.9, 15.2, 17.1, 19, 5])
>>> round(fit.intercept, 6), round(fit.slope, 6)
(1.082238, 1.994758)
"""

from bowden.identify.estimator import TransmissionIdentifier
from bowden.identify.figure import plot_identification, save_identification_figure
from bowden.identify.preprocess import (
    DIRECTIONS,
    LOWERING,
    RAISING,
    FilteredBench,
    PreprocessSettings,
    SteadyStateSelection,
    bench_filter,
    bench_preprocess,
    bench_select,
)
from bowden.identify.recording import (
    BenchRecording,
    BenchSource,
    RecordingLimits,
    bench_recording_from_frame,
    read_bench_recording,
)
from bowden.identify.robustfit import RobustFit, robustfit
from bowden.identify.summary import (
    DirectionSummary,
    IdentificationSummary,
    SummaryThresholds,
    identification_summary,
)

__all__ = [
    "DIRECTIONS",
    "LOWERING",
    "RAISING",
    "BenchRecording",
    "BenchSource",
    "DirectionSummary",
    "FilteredBench",
    "IdentificationSummary",
    "PreprocessSettings",
    "RecordingLimits",
    "RobustFit",
    "SteadyStateSelection",
    "SummaryThresholds",
    "TransmissionIdentifier",
    "bench_filter",
    "bench_preprocess",
    "bench_recording_from_frame",
    "bench_select",
    "identification_summary",
    "plot_identification",
    "read_bench_recording",
    "robustfit",
    "save_identification_figure",
]
