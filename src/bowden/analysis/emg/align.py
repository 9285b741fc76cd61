"""Put an EMG recording on the controller's time base: a known offset, or sync pulses both logged."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bowden.analysis.emg.signal import EmgSignal
from bowden.errors import ParameterError, RecordingError


def emg_align(
    emg: EmgSignal,
    *,
    sync_channel: str | None = None,
    controller_times_s: ArrayLike | None = None,
    offset_s: float | None = None,
) -> EmgSignal:
    """Put an EMG signal on the controller's time base.

    Either ``offset_s`` (controller time of the EMG's first sample, when both clocks are known to
    agree), or ``sync_channel`` plus ``controller_times_s``: the rising edges of the sync channel
    (crossings of the midpoint between its minimum and maximum) are matched one to one with the
    controller's logged pulse times. One pulse fixes the offset; two or more fit
    t_controller = a + b·t_emg by least squares, which also corrects the drift between the two
    clocks (the rate becomes rate/b). The sync channel is dropped from the result.
    """
    if offset_s is not None:
        if sync_channel is not None or controller_times_s is not None:
            raise ParameterError("give either offset_s or sync_channel with controller_times_s, not both")
        if not math.isfinite(offset_s):
            raise ParameterError(f"offset_s must be finite, got {offset_s}")
        return replace(emg, start_s=float(offset_s))
    if sync_channel is None or controller_times_s is None:
        raise ParameterError("emg_align needs offset_s, or sync_channel together with controller_times_s")
    events = np.asarray(controller_times_s, dtype=np.float64).ravel()
    edges = sync_edge_times(emg, sync_channel)
    if events.size == 0 or edges.size != events.size:
        raise RecordingError(
            f"sync channel {sync_channel!r} has {edges.size} rising edges but the controller logged "
            f"{events.size} pulses; they must match one to one"
        )
    if events.size == 1:
        slope, intercept = 1.0, float(events[0] - edges[0])
    else:
        slope, intercept = (float(v) for v in np.polyfit(edges, events, 1))
        residual = float(np.max(np.abs(intercept + slope * edges - events)))
        if residual > 2.0 / emg.rate_hz + 1e-3:
            raise RecordingError(
                "sync pulses do not line up with the controller's times "
                f"(largest misfit {residual * 1e3:.1f} ms)"
            )
    remaining = tuple(name for name in emg.channels if name != sync_channel)
    kept = emg.select(remaining)
    return replace(kept, start_s=intercept + slope * emg.start_s, rate_hz=emg.rate_hz / slope)


def sync_edge_times(emg: EmgSignal, sync_channel: str) -> NDArray[np.float64]:
    """Times (EMG clock, s) of the rising edges of a sync/trigger channel, interpolated within a sample."""
    x = np.asarray(emg.channel(sync_channel))
    low, high = float(np.min(x)), float(np.max(x))
    if not high > low:
        return np.empty(0)
    level = 0.5 * (low + high)
    above = x >= level
    rising = np.flatnonzero(~above[:-1] & above[1:])
    fraction = (level - x[rising]) / (x[rising + 1] - x[rising])
    return np.asarray(emg.start_s + (rising + fraction) / emg.rate_hz, dtype=np.float64)
