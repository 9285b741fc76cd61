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

from typing import TYPE_CHECKING

from bowden._lazy import lazy_exports

# robustfit shares its module's name: imported lazily, the package's attribute would become the module
# as soon as anything imported bowden.identify.robustfit. It is light (NumPy; its scipy.linalg and
# scipy.stats are imported inside). The settings are what the command line's parser reads.
from bowden.identify.robustfit import RobustFit, robustfit
from bowden.identify.settings import (
    DIRECTIONS,
    LOWERING,
    RAISING,
    PreprocessSettings,
)

# Imported on first use (PEP 562): ``bowden identify --help`` and ``bowden --help`` read the settings
# above and should not pay for pandas, SciPy's signal processing, statsmodels and matplotlib.
_EXPORTS = {
    "BenchRecording": "bowden.identify.recording",
    "BenchSource": "bowden.identify.recording",
    "DirectionSummary": "bowden.identify.summary",
    "FilteredBench": "bowden.identify.preprocess",
    "IdentificationSummary": "bowden.identify.summary",
    "RecordingLimits": "bowden.identify.recording",
    "SteadyStateSelection": "bowden.identify.preprocess",
    "SummaryThresholds": "bowden.identify.summary",
    "TransmissionIdentifier": "bowden.identify.estimator",
    "bench_filter": "bowden.identify.preprocess",
    "bench_preprocess": "bowden.identify.preprocess",
    "bench_recording_from_frame": "bowden.identify.recording",
    "bench_select": "bowden.identify.preprocess",
    "identification_summary": "bowden.identify.summary",
    "plot_identification": "bowden.identify.figure",
    "read_bench_recording": "bowden.identify.recording",
    "save_identification_figure": "bowden.identify.figure",
}

if TYPE_CHECKING:
    from bowden.identify.estimator import TransmissionIdentifier
    from bowden.identify.figure import plot_identification, save_identification_figure
    from bowden.identify.preprocess import (
        FilteredBench,
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
    from bowden.identify.summary import (
        DirectionSummary,
        IdentificationSummary,
        SummaryThresholds,
        identification_summary,
    )


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)


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
