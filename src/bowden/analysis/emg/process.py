"""The EMG pipeline of the paper as one call: check → R-peaks → band-pass → ECG removal → envelope.

:func:`emg_process` returns a labelled table (``time_s``, then ``<muscle>_clean_v`` and
``<muscle>_envelope_v`` per channel) and an :class:`EmgProcessInfo` saying what was done;
:func:`emg_pipeline` is the same without the table, for code that keeps working on signals.
R-peaks are detected on the *raw* channel (or a cleaner reference channel), because the 20 Hz
high-pass of the EMG band removes most of the QRS energy that the detector relies on; the template
is then subtracted from the band-passed EMG, and rectification and the RMS envelope follow.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from bowden.analysis.emg.check import EmgCheckParameters, emg_check
from bowden.analysis.emg.ecg import EcgRemovalParameters, remove_ecg_from_channel
from bowden.analysis.emg.filter import band_passed, emg_envelope
from bowden.analysis.emg.rpeaks import r_peaks_of_channels
from bowden.analysis.emg.signal import EmgSignal
from bowden.contracts import ECG_CONTAMINATED_MUSCLES, TRIAL_TIME
from bowden.errors import ParameterError

EcgRemoval = Literal["adaptive", "template", "none"]


@dataclass(frozen=True, kw_only=True)
class EmgProcessParameters:
    """Settings of the EMG pipeline; defaults reproduce the paper ("Data processing").

    Parameters
    ----------
    low_hz, high_hz, filter_order
        Zero-phase Butterworth band-pass (paper: 20–400 Hz, order 3).
    envelope_window_s
        Sliding RMS window, s (paper: 0.1).
    ecg_removal
        ``"adaptive"`` template subtraction (Petersen et al. 2020), the plain ``"template"``
        subtraction, or ``"none"``.
    ecg_channels
        Channels cleaned of ECG (paper: pectoralis major and latissimus dorsi); absent ones are skipped.
    ecg_reference_channel
        Channel on which R-peaks are detected for all ``ecg_channels`` (e.g. an ECG lead); ``None``
        detects on each contaminated channel itself.
    min_rr_s
        Refractory interval of the R-peak detector, s.
    min_rr_fraction
        Of two detected beats closer than this fraction of the median RR interval, the one less like
        the median beat is dropped (0: keep all); see :func:`~bowden.analysis.emg_detect_r_peaks`.
    ecg
        Details of the template subtraction (its ``method`` is overridden by ``ecg_removal``).
    check
        Channel checks run first; ``None`` skips them.
    """

    low_hz: float = 20.0
    high_hz: float = 400.0
    filter_order: int = 3
    envelope_window_s: float = 0.1
    ecg_removal: EcgRemoval = "adaptive"
    ecg_channels: tuple[str, ...] = ECG_CONTAMINATED_MUSCLES
    ecg_reference_channel: str | None = None
    min_rr_s: float = 0.3
    min_rr_fraction: float = 0.6
    ecg: EcgRemovalParameters = field(default_factory=EcgRemovalParameters)
    check: EmgCheckParameters | None = field(default_factory=EmgCheckParameters)

    def __post_init__(self) -> None:
        if self.ecg_removal not in ("adaptive", "template", "none"):
            raise ParameterError(
                f"ecg_removal must be 'adaptive', 'template' or 'none', got {self.ecg_removal!r}"
            )
        if not (isinstance(self.filter_order, int) and self.filter_order >= 1):
            raise ParameterError(f"filter_order must be a positive integer, got {self.filter_order!r}")
        if not (
            math.isfinite(self.low_hz) and math.isfinite(self.high_hz) and 0.0 < self.low_hz < self.high_hz
        ):
            raise ParameterError(f"need 0 < low_hz < high_hz, got {self.low_hz}, {self.high_hz}")
        if not (math.isfinite(self.envelope_window_s) and self.envelope_window_s > 0.0):
            raise ParameterError(f"envelope_window_s must be positive, got {self.envelope_window_s}")
        if not (math.isfinite(self.min_rr_s) and self.min_rr_s > 0.0):
            raise ParameterError(f"min_rr_s must be positive, got {self.min_rr_s}")
        if not (math.isfinite(self.min_rr_fraction) and 0.0 <= self.min_rr_fraction < 1.0):
            raise ParameterError(f"min_rr_fraction must be in [0, 1), got {self.min_rr_fraction}")


@dataclass(frozen=True, kw_only=True)
class EmgProcessInfo:
    """What :func:`emg_process` did to one recording.

    Attributes
    ----------
    rate_hz
        Sampling rate of the input and output, Hz.
    channels
        Channels processed, in table order.
    parameters
        The settings used.
    ecg_cleaned
        Channels from which the ECG was subtracted.
    r_peaks
        Channel → R-peak sample indices used to clean it.
    heart_rate_bpm
        Channel → mean heart rate from its R-peaks (NaN with fewer than two peaks), 1/min.
    """

    rate_hz: float
    channels: tuple[str, ...]
    parameters: EmgProcessParameters
    ecg_cleaned: tuple[str, ...]
    r_peaks: dict[str, NDArray[np.int64]]
    heart_rate_bpm: dict[str, float]


@dataclass(frozen=True, kw_only=True)
class EmgResult:
    """Signals produced by :func:`emg_pipeline`: cleaned (band-passed, ECG removed) and envelope, V."""

    clean: EmgSignal
    envelope: EmgSignal
    info: EmgProcessInfo


def emg_pipeline(emg: EmgSignal, parameters: EmgProcessParameters | None = None) -> EmgResult:
    """Run the paper's EMG processing on a raw signal (V) and keep the results as signals."""
    params = parameters or EmgProcessParameters()
    if params.check is not None:
        emg_check(emg, params.check)
    targets = tuple(name for name in params.ecg_channels if name in emg.channels)
    peaks: dict[str, NDArray[np.int64]] = {}
    detect = functools.partial(
        r_peaks_of_channels, emg, min_rr_s=params.min_rr_s, min_rr_fraction=params.min_rr_fraction
    )
    if params.ecg_removal != "none":
        if params.ecg_reference_channel is not None:
            shared = detect((params.ecg_reference_channel,))
            peaks = dict.fromkeys(targets, shared[params.ecg_reference_channel])
        elif targets:
            peaks = detect(targets)  # the detection copies filtered in one pass
    values = band_passed(emg, low_hz=params.low_hz, high_hz=params.high_hz, order=params.filter_order)
    if params.ecg_removal != "none" and targets:
        ecg_params = replace(params.ecg, method=params.ecg_removal)
        # Channel by channel (each may have its own R-peaks), written back into the band-passed array.
        for name in targets:
            i = emg.channels.index(name)
            values[:, i] = remove_ecg_from_channel(values[:, i], peaks[name], emg.rate_hz, ecg_params)
    filtered = emg.with_values(values, adopt=True)
    # The paper rectifies before the RMS window; |x|² = x², so the envelope of the rectified signal
    # is computed from the clean signal directly (emg_envelope's docstring), saving a full copy.
    envelope = emg_envelope(filtered, window_s=params.envelope_window_s)
    info = EmgProcessInfo(
        rate_hz=emg.rate_hz,
        channels=emg.channels,
        parameters=params,
        ecg_cleaned=targets if params.ecg_removal != "none" else (),
        r_peaks=peaks,
        heart_rate_bpm={name: _heart_rate_bpm(p, emg.rate_hz) for name, p in peaks.items()},
    )
    return EmgResult(clean=filtered, envelope=envelope, info=info)


def emg_process(
    emg: EmgSignal | pd.DataFrame, parameters: EmgProcessParameters | None = None
) -> tuple[pd.DataFrame, EmgProcessInfo]:
    """Process raw EMG into a labelled table and an info object.

    Parameters
    ----------
    emg
        Raw EMG, V: an :class:`EmgSignal`, or a DataFrame with ``time_s`` and one column per muscle.
    parameters
        Settings; defaults reproduce the paper.

    Returns
    -------
    table
        ``time_s``, then for every channel ``<channel>_clean_v`` (band-passed, ECG removed) and
        ``<channel>_envelope_v`` (100 ms RMS of the rectified clean signal).
    info
        :class:`EmgProcessInfo`.

    Examples
    --------
    >>> import numpy as np
    >>> from bowden.analysis import EmgSignal, EmgProcessParameters, emg_process
    >>> t = np.arange(4000) / 2000.0
    >>> raw = EmgSignal(values=1e-4 * np.sin(2 * np.pi * 100.0 * t), rate_hz=2000.0, channels=("biceps",))
    >>> table, info = emg_process(raw, EmgProcessParameters(check=None))
    >>> list(table.columns)
    ['time_s', 'biceps_clean_v', 'biceps_envelope_v']
    >>> round(float(table["biceps_envelope_v"].iloc[2000]) / 1e-4, 3)
    0.707
    """
    signal = EmgSignal.from_frame(emg) if isinstance(emg, pd.DataFrame) else emg
    result = emg_pipeline(signal, parameters)
    columns: dict[str, NDArray[np.float64]] = {TRIAL_TIME: signal.time_s}
    for name in signal.channels:
        columns[f"{name}_clean_v"] = np.asarray(result.clean.channel(name))
        columns[f"{name}_envelope_v"] = np.asarray(result.envelope.channel(name))
    return pd.DataFrame(columns), result.info


def _heart_rate_bpm(peaks: NDArray[np.int64], rate_hz: float) -> float:
    if peaks.size < 2:
        return math.nan
    return 60.0 * rate_hz / float(np.mean(np.diff(peaks)))
