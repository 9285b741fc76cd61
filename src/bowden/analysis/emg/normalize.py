"""Amplitude normalisation of EMG envelopes to the no-suit condition.

Paper ("Data processing"): "The EMG envelope amplitude was normalized to the average maximum peak of
the no-suit condition, separately for each participant and velocity." :func:`emg_mean_peak` computes
that reference from one no-suit trial (the mean over the kept repetitions of each repetition's
peak) and :func:`emg_normalize` divides any envelope of the same participant and speed by it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from bowden.analysis.emg.signal import EmgSignal
from bowden.analysis.segmentation import Repetition
from bowden.errors import RecordingError


def emg_mean_peak(envelope: EmgSignal, repetitions: Iterable[Repetition]) -> dict[str, float]:
    """Mean over repetitions of each channel's peak envelope within the repetition, V.

    Parameters
    ----------
    envelope
        EMG envelope on the controller's time base, V.
    repetitions
        The repetitions kept for analysis (first one already dropped).
    """
    reps = list(repetitions)
    if not reps:
        raise RecordingError("emg_mean_peak needs at least one repetition")
    time = envelope.time_s
    peaks = []
    for rep in reps:
        inside = (time >= rep.start_s) & (time <= rep.end_s)
        if not np.any(inside):
            raise RecordingError(
                f"repetition {rep.number} ({rep.start_s:.3f}–{rep.end_s:.3f} s) has no EMG samples "
                f"(EMG covers {time[0]:.3f}–{time[-1]:.3f} s); is the EMG aligned to the controller?"
            )
        peaks.append(envelope.values[inside].max(axis=0))
    mean = np.mean(peaks, axis=0)
    return {name: float(value) for name, value in zip(envelope.channels, mean, strict=True)}


def emg_normalize(envelope: EmgSignal, reference: Mapping[str, float]) -> EmgSignal:
    """Divide each channel by its reference amplitude (dimensionless result; 1 = mean no-suit peak).

    Raises :class:`~bowden.errors.RecordingError` when a channel has no reference or a reference
    that is not positive.
    """
    scale = []
    for name in envelope.channels:
        if name not in reference:
            raise RecordingError(f"no normalisation reference for EMG channel {name!r}")
        value = float(reference[name])
        if not (np.isfinite(value) and value > 0.0):
            raise RecordingError(
                f"normalisation reference of channel {name!r} is {value}; it must be positive"
            )
        scale.append(value)
    return envelope.with_values(envelope.values / np.asarray(scale), adopt=True)
