"""Study analysis: EMG with ECG removal, segmentation, and the paper's outcome measures.

Each EMG step is an ``emg_<verb>`` function on an :class:`EmgSignal` (the sampling rate travels
with the samples); :func:`emg_process` composes them into the paper's pipeline. Trials are
segmented into repetitions and phases on normalised time; :func:`analyse_trial` computes one
trial's measures and :func:`analyse_study` turns a study's DataFrames into the tidy outcome table
and mean ± SD curves; :func:`methods_text` describes it all.
"""

from typing import TYPE_CHECKING

from bowden._lazy import lazy_exports

# The function sparc shares its module's name: imported lazily, the package's attribute would become
# the module as soon as anything imported bowden.analysis.sparc. It is light (NumPy only).
from bowden.analysis.sparc import SparcParameters, sparc

# Imported on first use (PEP 562): a light module of this package (the EMG import's constants, the
# command line's choices) should not pay for pandas, SciPy and numba (seconds of start-up).
_EXPORTS = {
    "AnalysisInfo": "bowden.analysis.outcomes",
    "AnalysisParameters": "bowden.analysis.outcomes",
    "EcgRemovalParameters": "bowden.analysis.emg",
    "EmgCheckParameters": "bowden.analysis.emg",
    "EmgProcessInfo": "bowden.analysis.emg",
    "EmgProcessParameters": "bowden.analysis.emg",
    "EmgResult": "bowden.analysis.emg",
    "EmgSignal": "bowden.analysis.emg",
    "MethodsText": "bowden.analysis.methods",
    "Repetition": "bowden.analysis.segmentation",
    "Segmentation": "bowden.analysis.segmentation",
    "SegmentationParameters": "bowden.analysis.segmentation",
    "StudyOutcomes": "bowden.analysis.outcomes",
    "TrialMetadata": "bowden.analysis.outcomes",
    "TrialOutcomes": "bowden.analysis.trial_outcomes",
    "analyse_study": "bowden.analysis.outcomes",
    "analyse_trial": "bowden.analysis.trial_outcomes",
    "emg_align": "bowden.analysis.emg",
    "emg_check": "bowden.analysis.emg",
    "emg_detect_r_peaks": "bowden.analysis.emg",
    "emg_envelope": "bowden.analysis.emg",
    "emg_filter": "bowden.analysis.emg",
    "emg_mean_peak": "bowden.analysis.emg",
    "emg_normalize": "bowden.analysis.emg",
    "emg_pipeline": "bowden.analysis.emg",
    "emg_process": "bowden.analysis.emg",
    "emg_rectify": "bowden.analysis.emg",
    "emg_remove_ecg": "bowden.analysis.emg",
    "methods_text": "bowden.analysis.methods",
    "read_emg_csv": "bowden.analysis.emg",
    "read_emg_edf": "bowden.analysis.emg",
    "resample_repetition": "bowden.analysis.segmentation",
    "segment_repetitions": "bowden.analysis.segmentation",
}

if TYPE_CHECKING:
    from bowden.analysis.emg import (
        EcgRemovalParameters,
        EmgCheckParameters,
        EmgProcessInfo,
        EmgProcessParameters,
        EmgResult,
        EmgSignal,
        emg_align,
        emg_check,
        emg_detect_r_peaks,
        emg_envelope,
        emg_filter,
        emg_mean_peak,
        emg_normalize,
        emg_pipeline,
        emg_process,
        emg_rectify,
        emg_remove_ecg,
        read_emg_csv,
        read_emg_edf,
    )
    from bowden.analysis.methods import MethodsText, methods_text
    from bowden.analysis.outcomes import (
        AnalysisInfo,
        AnalysisParameters,
        StudyOutcomes,
        TrialMetadata,
        analyse_study,
    )
    from bowden.analysis.segmentation import (
        Repetition,
        Segmentation,
        SegmentationParameters,
        resample_repetition,
        segment_repetitions,
    )
    from bowden.analysis.trial_outcomes import TrialOutcomes, analyse_trial


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)


__all__ = [
    "AnalysisInfo",
    "AnalysisParameters",
    "EcgRemovalParameters",
    "EmgCheckParameters",
    "EmgProcessInfo",
    "EmgProcessParameters",
    "EmgResult",
    "EmgSignal",
    "MethodsText",
    "Repetition",
    "Segmentation",
    "SegmentationParameters",
    "SparcParameters",
    "StudyOutcomes",
    "TrialMetadata",
    "TrialOutcomes",
    "analyse_study",
    "analyse_trial",
    "emg_align",
    "emg_check",
    "emg_detect_r_peaks",
    "emg_envelope",
    "emg_filter",
    "emg_mean_peak",
    "emg_normalize",
    "emg_pipeline",
    "emg_process",
    "emg_rectify",
    "emg_remove_ecg",
    "methods_text",
    "read_emg_csv",
    "read_emg_edf",
    "resample_repetition",
    "segment_repetitions",
    "sparc",
]
