"""Study analysis: EMG with ECG removal, segmentation, and the paper's outcome measures.

Each EMG step is an ``emg_<verb>`` function on an :class:`EmgSignal` (the sampling rate travels
with the samples); :func:`emg_process` composes them into the paper's pipeline. Trials are
segmented into repetitions and phases on normalised time; :func:`analyse_trial` computes one
trial's measures and :func:`analyse_study` turns a study's DataFrames into the tidy outcome table
and mean ± SD curves; :func:`methods_text` describes it all.
"""

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
from bowden.analysis.methods_text import MethodsText, methods_text
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
from bowden.analysis.sparc import SparcParameters, sparc
from bowden.analysis.trial_outcomes import TrialOutcomes, analyse_trial

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
