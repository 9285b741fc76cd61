"""The EMG signal container: samples, channel names and the sampling rate travel together.

Choice (the sampling rate travels with the data): a small frozen dataclass rather than
``DataFrame.attrs``. pandas does not promise to carry ``attrs`` through every operation (concat,
arithmetic, groupby drop or mangle them), so a rate stored there can vanish silently; a dataclass
cannot lose its rate, is checked once on construction, and mypy sees the field. Every ``emg_<verb>``
function takes an :class:`EmgSignal` and returns a new one, so no ``fs`` argument can disagree with
the data. :meth:`EmgSignal.from_frame` and :meth:`EmgSignal.to_frame` convert from and to the
study's DataFrame layout (``time_s`` plus one column per muscle, see ``bowden.contracts``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from bowden.contracts import TRIAL_TIME
from bowden.errors import ParameterError, RecordingError

# Relative jitter of the sample interval that still counts as a uniform sampling rate.
_RATE_JITTER_TOLERANCE = 1e-3


@dataclass(frozen=True, kw_only=True)
class EmgSignal:
    """Uniformly sampled multi-channel signal.

    Parameters
    ----------
    values
        Samples, shape (n_samples, n_channels) or (n_samples,) for one channel; stored as a
        read-only float64 array of shape (n_samples, n_channels). Volts for raw EMG.
    rate_hz
        Sampling rate, Hz.
    channels
        One name per column (paper: ``bowden.contracts.MUSCLES``). Defaults to ``ch0, ch1, ...``.
    start_s
        Time of the first sample on the controller's time base, s.
    """

    values: NDArray[np.float64]
    rate_hz: float
    channels: tuple[str, ...] = field(default=())
    start_s: float = 0.0

    def __post_init__(self) -> None:
        values = np.asarray(self.values, dtype=np.float64)
        if values.ndim == 1:
            values = values[:, np.newaxis]
        if values.ndim != 2:
            raise ParameterError(f"values must be 1-D or 2-D (samples x channels), got shape {values.shape}")
        if values.flags.writeable:
            # Never freeze the caller's array: keep a private read-only copy instead.
            values = values.copy()
            values.flags.writeable = False
        object.__setattr__(self, "values", values)
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0.0):
            raise ParameterError(f"rate_hz must be a positive number, got {self.rate_hz}")
        if not math.isfinite(self.start_s):
            raise ParameterError(f"start_s must be finite, got {self.start_s}")
        channels = tuple(self.channels) or tuple(f"ch{i}" for i in range(values.shape[1]))
        if len(channels) != values.shape[1]:
            raise ParameterError(f"channels names {len(channels)} columns but values has {values.shape[1]}")
        if len(set(channels)) != len(channels):
            raise ParameterError(f"channels must be unique, got {channels}")
        object.__setattr__(self, "channels", channels)

    @property
    def n_samples(self) -> int:
        """Number of samples per channel."""
        return int(self.values.shape[0])

    @property
    def time_s(self) -> NDArray[np.float64]:
        """Sample times on the controller's time base, s."""
        return self.start_s + np.arange(self.n_samples, dtype=np.float64) / self.rate_hz

    @property
    def duration_s(self) -> float:
        """Length of the recording, s (n_samples / rate_hz)."""
        return self.n_samples / self.rate_hz

    def channel(self, name: str) -> NDArray[np.float64]:
        """Samples of one channel (read-only view)."""
        try:
            index = self.channels.index(name)
        except ValueError:
            raise RecordingError(
                f"EMG channel {name!r} not found; channels are {list(self.channels)}"
            ) from None
        return self.values[:, index]

    def with_values(
        self, values: ArrayLike, channels: Sequence[str] | None = None, *, adopt: bool = False
    ) -> EmgSignal:
        """A signal with the same rate and start but new samples (same length or not).

        ``adopt=True`` takes ownership of a freshly computed float64 array (it is made read-only
        instead of copied); processing steps use it to avoid copying every intermediate result.
        """
        array = np.asarray(values, dtype=np.float64)
        if adopt and array.flags.owndata:
            array.flags.writeable = False
        return replace(self, values=array, channels=tuple(self.channels if channels is None else channels))

    def select(self, channels: Sequence[str]) -> EmgSignal:
        """The named channels only, in the given order."""
        columns = [self.channel(name) for name in channels]
        return self.with_values(
            np.column_stack(columns) if columns else np.empty((self.n_samples, 0)), channels
        )

    @classmethod
    def from_frame(
        cls,
        frame: pd.DataFrame,
        *,
        channels: Sequence[str] | None = None,
        time_column: str = TRIAL_TIME,
    ) -> EmgSignal:
        """Build a signal from a DataFrame with a time column (s) and one column per channel.

        The rate is the reciprocal of the median sample interval. Raises
        :class:`~bowden.errors.RecordingError` naming the row when time is missing, not strictly
        increasing, or not uniform (jitter above 0.1 % of the interval), and naming the column when a
        channel is missing or not numeric.
        """
        if time_column not in frame.columns:
            raise RecordingError(
                f"EMG table has no {time_column!r} column; columns are {list(frame.columns)}"
            )
        names = [str(c) for c in frame.columns if c != time_column] if channels is None else list(channels)
        missing = [name for name in names if name not in frame.columns]
        if missing:
            raise RecordingError(
                f"EMG table lacks channel column(s) {missing}; columns are {list(frame.columns)}"
            )
        time = _numeric_column(frame, time_column)
        rate_hz = rate_from_time(time, what=f"EMG column {time_column!r}")
        data = (
            np.column_stack([_numeric_column(frame, name) for name in names])
            if names
            else np.empty((len(time), 0))
        )
        return cls(values=data, rate_hz=rate_hz, channels=tuple(names), start_s=float(time[0]))

    def to_frame(self, *, time_column: str = TRIAL_TIME) -> pd.DataFrame:
        """DataFrame with the time column first and one column per channel."""
        frame = pd.DataFrame(np.asarray(self.values), columns=list(self.channels))
        frame.insert(0, time_column, self.time_s)
        return frame


def rate_from_time(time_s: NDArray[np.float64], *, what: str = "time") -> float:
    """Sampling rate (Hz) of a uniformly sampled time vector; clear errors otherwise.

    Raises :class:`~bowden.errors.RecordingError` naming the first offending row for NaN times,
    times that do not increase, and sample intervals that deviate from the median by more than 0.1 %.
    """
    if time_s.size < 2:
        raise RecordingError(f"{what}: need at least 2 samples to know the sampling rate, got {time_s.size}")
    bad = np.flatnonzero(~np.isfinite(time_s))
    if bad.size:
        raise RecordingError(f"{what}: time is not finite at row {int(bad[0])}")
    step = np.diff(time_s)
    bad = np.flatnonzero(step <= 0.0)
    if bad.size:
        raise RecordingError(f"{what}: time does not increase at row {int(bad[0]) + 1}")
    median_step = float(np.median(step))
    bad = np.flatnonzero(np.abs(step - median_step) > _RATE_JITTER_TOLERANCE * median_step)
    if bad.size:
        raise RecordingError(
            f"{what}: sampling is not uniform at row {int(bad[0]) + 1} (interval {step[bad[0]]:.6g} s, "
            f"median {median_step:.6g} s); resample the recording first"
        )
    # The mean interval over the whole record is more precise than the median of rounded diffs.
    return float((time_s.size - 1) / (time_s[-1] - time_s[0]))


def _numeric_column(frame: pd.DataFrame, name: str) -> NDArray[np.float64]:
    try:
        return np.asarray(pd.to_numeric(frame[name], errors="raise"), dtype=np.float64)
    except (ValueError, TypeError) as exc:
        raise RecordingError(f"EMG column {name!r} is not numeric: {exc}") from None
