"""EMG channel checks: refuse channels that are missing, flat, clipped or at the wrong rate, by name."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from bowden.analysis.emg._kernels import channel_screen
from bowden.analysis.emg.signal import EmgSignal
from bowden.contracts import EMG_RATE_HZ, MUSCLES
from bowden.errors import ParameterError, RecordingError


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
    # One row-wise screen of all channels; only a channel it cannot clear is scanned on its own.
    nonfinite, repeats, screen_std = channel_screen(np.ascontiguousarray(emg.values))
    for name in judged:
        column = emg.channels.index(name)
        if nonfinite[column] == 0 and not repeats[column] and screen_std[column] >= 2.0 * params.flat_std_v:
            continue  # finite, never stuck, not flat (with margin for the screen's rounding): usable
        x = np.ascontiguousarray(emg.values[:, column])
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


def _runs_of_equal(x: NDArray[np.float64]) -> list[tuple[int, int]]:
    """(first index, length) of every run of identical consecutive samples longer than one."""
    equal = x[1:] == x[:-1]
    if not equal.any():  # the usual case for live EMG: answer without building run arrays
        return []
    edges = np.diff(np.concatenate([[False], equal, [False]]).astype(np.int8))
    starts = np.flatnonzero(edges == 1)
    stops = np.flatnonzero(edges == -1)  # x[starts[i] : stops[i] + 1] are all equal
    return [(int(s), int(e - s + 1)) for s, e in zip(starts, stops, strict=True)]
