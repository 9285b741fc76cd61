"""EMG inputs: EDF/BDF and CSV files, channel checks, alignment to the controller's time base.

EDF and BDF files are read with ``edfio`` (the ``emg`` extra: pure Python, maintained by MNE
developers); CSV files with pandas. Every reader returns an
:class:`~bowden.analysis.emg_signal.EmgSignal` in volts. :func:`emg_check` then refuses channels that
are missing, flat, clipped or sampled at the wrong rate, naming each problem, and :func:`emg_align`
moves the signal onto the controller's clock using a sync channel (trigger pulses that the
controller also logged) or a known offset.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from bowden.analysis.emg_signal import EmgSignal
from bowden.contracts import EMG_RATE_HZ, MUSCLES, TRIAL_TIME
from bowden.errors import ParameterError, RecordingError

# Physical dimensions found in EDF/BDF headers and their factor to volts.
_VOLT_SCALE = {"v": 1.0, "mv": 1e-3, "uv": 1e-6, "µv": 1e-6, "μv": 1e-6, "nv": 1e-9}


@dataclass(frozen=True, kw_only=True)
class EmgCheckParameters:
    """Thresholds of :func:`emg_check`.

    Parameters
    ----------
    expected_channels
        Channels that must be present (paper: the eight muscles of ``bowden.contracts.MUSCLES``).
    expected_rate_hz
        Required sampling rate, Hz (paper: 2000); ``None`` accepts any rate.
    rate_tolerance
        Accepted relative deviation from ``expected_rate_hz`` (clock drift, 1 %).
    flat_std_v
        A channel whose standard deviation is below this is flat (disconnected), V. Surface EMG
        noise alone is a few µV, so 0.1 µV is far below any live electrode.
    max_stuck_s
        Longest run of identical samples away from the rails before a channel counts as flat
        (stuck amplifier or dropped packets), s.
    max_clipped_fraction
        Largest fraction of samples sitting at the channel's minimum or maximum, in runs of three or
        more, before the channel counts as clipped.
    """

    expected_channels: tuple[str, ...] = MUSCLES
    expected_rate_hz: float | None = EMG_RATE_HZ
    rate_tolerance: float = 0.01
    flat_std_v: float = 1e-7
    max_stuck_s: float = 0.25
    max_clipped_fraction: float = 0.001

    def __post_init__(self) -> None:
        if self.expected_rate_hz is not None and not (
            math.isfinite(self.expected_rate_hz) and self.expected_rate_hz > 0.0
        ):
            raise ParameterError(f"expected_rate_hz must be positive or None, got {self.expected_rate_hz}")
        for name in ("rate_tolerance", "flat_std_v", "max_stuck_s", "max_clipped_fraction"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ParameterError(f"{name} must be a non-negative number, got {value}")


def emg_check(emg: EmgSignal, parameters: EmgCheckParameters | None = None) -> None:
    """Raise :class:`~bowden.errors.RecordingError` listing every unusable channel.

    Checks, in order: sampling rate, missing channels (absent, or with non-finite samples), flat
    channels (tiny standard deviation or a long stuck run), clipped channels (many samples at the
    rails). Only the expected channels are judged (all channels when none is expected), so a sync
    channel may stay in the signal. Returns ``None`` when the recording is usable.
    """
    params = parameters or EmgCheckParameters()
    problems: list[str] = []
    if params.expected_rate_hz is not None and (
        abs(emg.rate_hz - params.expected_rate_hz) > params.rate_tolerance * params.expected_rate_hz
    ):
        problems.append(
            f"sampling rate is {emg.rate_hz:g} Hz, expected {params.expected_rate_hz:g} Hz "
            "(resample the recording or set expected_rate_hz)"
        )
    for name in params.expected_channels:
        if name not in emg.channels:
            problems.append(f"channel {name!r} is missing (channels are {list(emg.channels)})")
    stuck_limit = max(2, round(params.max_stuck_s * emg.rate_hz))
    # Only the channels the analysis uses are judged: a sync or trigger channel is meant to clip.
    judged = [name for name in emg.channels if name in params.expected_channels] or list(emg.channels)
    by_channel = np.ascontiguousarray(emg.values.T)  # one row per channel: fast per-channel scans
    for name in judged:
        x = by_channel[emg.channels.index(name)]
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            problems.append(
                f"channel {name!r} is missing data: {bad.size} non-finite samples from sample {bad[0]}"
            )
            continue
        std = float(np.std(x))
        if std < params.flat_std_v:
            problems.append(f"channel {name!r} is flat (standard deviation {std:.3g} V)")
            continue
        runs = _runs_of_equal(x)
        if not runs:
            continue  # no two equal neighbours: neither clipped nor stuck
        tolerance = 1e-9 * (x.max() - x.min())
        at_rail = (x >= x.max() - tolerance) | (x <= x.min() + tolerance)
        clipped = int(sum(length for first, length in runs if length >= 3 and at_rail[first]))
        if clipped > params.max_clipped_fraction * x.size:
            problems.append(
                f"channel {name!r} is clipped: {clipped} samples ({100.0 * clipped / x.size:.2f} %) sit at "
                f"its limits {x.min():.4g} / {x.max():.4g} V"
            )
            continue
        stuck = [(first, length) for first, length in runs if length >= stuck_limit and not at_rail[first]]
        if stuck:
            first, length = max(stuck, key=lambda run: run[1])
            problems.append(
                f"channel {name!r} is flat for {length / emg.rate_hz:.3f} s from sample {first} "
                "(stuck signal)"
            )
    if problems:
        raise RecordingError("EMG recording unusable:\n  " + "\n  ".join(problems))


def read_emg_edf(
    path: str | Path,
    *,
    channel_map: Mapping[str, str] | None = None,
    channels: Sequence[str] | None = None,
) -> EmgSignal:
    """Read EMG channels from an EDF/EDF+ or BDF/BDF+ file (by extension) into volts.

    Parameters
    ----------
    path
        ``.edf`` or ``.bdf`` file.
    channel_map
        File label → channel name (e.g. ``{"EMG1": "anterior_deltoid"}``); unmapped labels keep
        their name.
    channels
        Channel names (after mapping) to read; ``None`` reads all signals except EDF annotations.
        All selected signals must share one sampling rate.
    """
    try:
        import edfio
    except ImportError:  # pragma: no cover - depends on the install
        raise RecordingError("reading EDF/BDF needs the 'emg' extra: pip install 'bowden[emg]'") from None
    file = Path(path)
    if not file.is_file():
        raise RecordingError(f"EMG file {file} does not exist")
    reader = edfio.read_bdf if file.suffix.lower() == ".bdf" else edfio.read_edf
    try:
        recording = reader(file)
    except (ValueError, OSError) as exc:
        raise RecordingError(f"{file.name} is not a readable {file.suffix.upper()[1:]} file: {exc}") from None
    mapping = dict(channel_map or {})
    by_name = {mapping.get(signal.label, signal.label): signal for signal in recording.signals}
    names = list(by_name) if channels is None else list(channels)
    missing = [name for name in names if name not in by_name]
    if missing:
        raise RecordingError(f"{file.name} lacks channel(s) {missing}; it has {list(by_name)}")
    rates = {name: float(by_name[name].sampling_frequency) for name in names}
    if len(set(rates.values())) > 1:
        raise RecordingError(
            f"{file.name}: channels have different sampling rates {rates}; read them separately"
        )
    columns = []
    for name in names:
        signal = by_name[name]
        unit = signal.physical_dimension.strip().lower()
        if unit not in _VOLT_SCALE:
            raise RecordingError(
                f"{file.name}: channel {name!r} has physical dimension {signal.physical_dimension!r}, "
                f"expected one of V, mV, uV"
            )
        columns.append(np.asarray(signal.data, dtype=np.float64) * _VOLT_SCALE[unit])
    if not columns:
        raise RecordingError(f"{file.name} has no signals to read")
    return EmgSignal(
        values=np.column_stack(columns), rate_hz=next(iter(rates.values())), channels=tuple(names)
    )


def read_emg_csv(
    path: str | Path,
    *,
    time_column: str = TRIAL_TIME,
    channels: Sequence[str] | None = None,
    volts_per_unit: float = 1.0,
) -> EmgSignal:
    """Read EMG from a CSV file with a time column (s) and one column per channel.

    ``volts_per_unit`` converts the file's unit (1e-6 for µV). The rate comes from the time column,
    which must be uniform (see :meth:`EmgSignal.from_frame`).
    """
    file = Path(path)
    if not file.is_file():
        raise RecordingError(f"EMG file {file} does not exist")
    if not (math.isfinite(volts_per_unit) and volts_per_unit > 0.0):
        raise ParameterError(f"volts_per_unit must be positive, got {volts_per_unit}")
    try:
        frame = pd.read_csv(file)
    except (ValueError, OSError) as exc:
        raise RecordingError(f"{file.name} is not a readable CSV file: {exc}") from None
    signal = EmgSignal.from_frame(frame, channels=channels, time_column=time_column)
    return signal.with_values(signal.values * volts_per_unit) if volts_per_unit != 1.0 else signal


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


def _runs_of_equal(x: NDArray[np.float64]) -> list[tuple[int, int]]:
    """(first index, length) of every run of identical consecutive samples longer than one."""
    equal = x[1:] == x[:-1]
    if not equal.any():  # the usual case for live EMG: answer without building run arrays
        return []
    edges = np.diff(np.concatenate([[False], equal, [False]]).astype(np.int8))
    starts = np.flatnonzero(edges == 1)
    stops = np.flatnonzero(edges == -1)  # x[starts[i] : stops[i] + 1] are all equal
    return [(int(s), int(e - s + 1)) for s, e in zip(starts, stops, strict=True)]
