"""EMG: the signal container, files, checks, clock alignment, filtering, ECG removal, the pipeline.

Each step is an ``emg_<verb>`` function on an :class:`EmgSignal` (the sampling rate travels with the
samples); :func:`emg_process` composes them into the paper's pipeline. Files come in through
:func:`read_emg_edf`, :func:`read_emg_csv` and :func:`read_emg_xdf`; :func:`emg_check` refuses
unusable channels; :func:`emg_align` and :func:`clock_fit` put a recording on the controller's clock.
"""

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
