"""EMG: the signal container, files, checks, clock alignment, filtering, ECG removal, the pipeline.

Each step is an ``emg_<verb>`` function on an :class:`EmgSignal` (the sampling rate travels with the
samples); :func:`emg_process` composes them into the paper's pipeline. Files come in through
:func:`read_emg_edf`, :func:`read_emg_csv` and :func:`read_emg_xdf`; :func:`emg_check` refuses
unusable channels; :func:`emg_align` and :func:`clock_fit` put a recording on the controller's clock.
"""

from typing import TYPE_CHECKING

from bowden._lazy import lazy_exports

# Imported on first use (PEP 562), like bowden.analysis: one EMG module (the import's constants, the
# channel maps) should not pay for every other one's SciPy and numba.
_EXPORTS = {
    "ClockFit": "bowden.analysis.emg.sync",
    "EcgRemovalParameters": "bowden.analysis.emg.ecg",
    "EmgCheckParameters": "bowden.analysis.emg.check",
    "EmgProcessInfo": "bowden.analysis.emg.process",
    "EmgProcessParameters": "bowden.analysis.emg.process",
    "EmgResult": "bowden.analysis.emg.process",
    "EmgSignal": "bowden.analysis.emg.signal",
    "SAGA_CHANNELS": "bowden.analysis.emg.channels",
    "XdfRecording": "bowden.analysis.emg.xdf",
    "clock_fit": "bowden.analysis.emg.sync",
    "emg_align": "bowden.analysis.emg.align",
    "emg_check": "bowden.analysis.emg.check",
    "emg_detect_r_peaks": "bowden.analysis.emg.rpeaks",
    "emg_envelope": "bowden.analysis.emg.filter",
    "emg_filter": "bowden.analysis.emg.filter",
    "emg_map_channels": "bowden.analysis.emg.channels",
    "emg_mean_peak": "bowden.analysis.emg.normalize",
    "emg_normalize": "bowden.analysis.emg.normalize",
    "emg_pipeline": "bowden.analysis.emg.process",
    "emg_process": "bowden.analysis.emg.process",
    "emg_rectify": "bowden.analysis.emg.filter",
    "emg_remove_ecg": "bowden.analysis.emg.ecg",
    "load_channel_map": "bowden.analysis.emg.channels",
    "match_pulses": "bowden.analysis.emg.sync",
    "read_emg_csv": "bowden.analysis.emg.read",
    "read_emg_edf": "bowden.analysis.emg.read",
    "read_emg_xdf": "bowden.analysis.emg.xdf",
    "sync_edge_times": "bowden.analysis.emg.align",
    "trigger_pulses": "bowden.analysis.emg.sync",
}

if TYPE_CHECKING:
    from bowden.analysis.emg.align import emg_align, sync_edge_times
    from bowden.analysis.emg.channels import SAGA_CHANNELS, emg_map_channels, load_channel_map
    from bowden.analysis.emg.check import EmgCheckParameters, emg_check
    from bowden.analysis.emg.ecg import EcgRemovalParameters, emg_remove_ecg
    from bowden.analysis.emg.filter import emg_envelope, emg_filter, emg_rectify
    from bowden.analysis.emg.normalize import emg_mean_peak, emg_normalize
    from bowden.analysis.emg.process import (
        EmgProcessInfo,
        EmgProcessParameters,
        EmgResult,
        emg_pipeline,
        emg_process,
    )
    from bowden.analysis.emg.read import read_emg_csv, read_emg_edf
    from bowden.analysis.emg.rpeaks import emg_detect_r_peaks
    from bowden.analysis.emg.signal import EmgSignal
    from bowden.analysis.emg.sync import ClockFit, clock_fit, match_pulses, trigger_pulses
    from bowden.analysis.emg.xdf import XdfRecording, read_emg_xdf


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)


__all__ = [
    "SAGA_CHANNELS",
    "ClockFit",
    "EcgRemovalParameters",
    "EmgCheckParameters",
    "EmgProcessInfo",
    "EmgProcessParameters",
    "EmgResult",
    "EmgSignal",
    "XdfRecording",
    "clock_fit",
    "emg_align",
    "emg_check",
    "emg_detect_r_peaks",
    "emg_envelope",
    "emg_filter",
    "emg_map_channels",
    "emg_mean_peak",
    "emg_normalize",
    "emg_pipeline",
    "emg_process",
    "emg_rectify",
    "emg_remove_ecg",
    "load_channel_map",
    "match_pulses",
    "read_emg_csv",
    "read_emg_edf",
    "read_emg_xdf",
    "sync_edge_times",
    "trigger_pulses",
]
