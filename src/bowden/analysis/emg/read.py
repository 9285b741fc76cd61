"""EMG files: EDF/BDF and CSV recordings into an :class:`~bowden.analysis.emg.signal.EmgSignal` in volts.

EDF and BDF files are read with ``edfio`` (the ``emg`` extra: pure Python, maintained by MNE
developers); CSV files with pandas. XDF files (Lab Streaming Layer) are read by
:mod:`bowden.analysis.emg.xdf`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from bowden.analysis.emg.signal import EmgSignal
from bowden.contracts import TRIAL_TIME
from bowden.errors import ParameterError, RecordingError

# Physical dimensions found in EDF/BDF headers and their factor to volts.
_VOLT_SCALE = {"v": 1.0, "mv": 1e-3, "uv": 1e-6, "µv": 1e-6, "μv": 1e-6, "nv": 1e-9,
               # spelled out, as XDF's meta-data conventions write them
               "volts": 1.0, "millivolts": 1e-3, "microvolts": 1e-6, "nanovolts": 1e-9,
               # as TMSi's devices name their units ("µVolt"; TMSi Python Interface, poly5reader.py)
               "volt": 1.0, "mvolt": 1e-3, "uvolt": 1e-6, "µvolt": 1e-6, "μvolt": 1e-6}


def volt_scale(unit: str, *, default: float | None = None) -> float:
    """Factor from a file's unit (``"uV"``, ``"mV"``...) to volts; ``default`` for an empty unit.

    Raises
    ------
    RecordingError
        For a unit that is not a voltage.
    """
    key = unit.strip().lower()
    if key in _VOLT_SCALE:
        return _VOLT_SCALE[key]
    if not key and default is not None:
        return default
    raise RecordingError(f"unit {unit!r} is not a voltage (expected one of V, mV, uV)")


@dataclass(frozen=True)
class SourceChannel:
    """One channel's samples as its file stores them: ``volts = codes × gain_v + offset_v``.

    ``codes`` are the file's own numbers: EDF's 16-bit and BDF's 24-bit digital codes (int16, int32)
    with the header's physical/digital scaling folded into ``gain_v`` and ``offset_v``, or the float32 /
    float64 values of an XDF stream or a CSV column with their unit's factor. The study store keeps
    them as they are, so an imported recording loses no resolution (:mod:`bowden.store.emg_chunks`).
    """

    codes: NDArray[Any]
    gain_v: float
    offset_v: float = 0.0

    def volts(self) -> NDArray[np.float64]:
        """The samples in volts (the store decodes them with the same arithmetic)."""
        return decode_source(self.codes, self.gain_v, self.offset_v)

    def select(self, first: int, stop: int) -> SourceChannel:
        return SourceChannel(codes=self.codes[first:stop], gain_v=self.gain_v, offset_v=self.offset_v)


def decode_source(codes: NDArray[Any], gain_v: float, offset_v: float) -> NDArray[np.float64]:
    """``codes × gain_v + offset_v`` in float64: the one formula the reader and the store use."""
    volts = np.asarray(codes, dtype=np.float64) * gain_v
    return volts + offset_v if offset_v else volts


@dataclass(frozen=True)
class SourceRecording:
    """A recording in volts (``signal``) and, per voltage channel, its samples as the file stores them."""

    signal: EmgSignal
    sources: Mapping[str, SourceChannel]


def read_emg_edf(
    path: str | Path,
    *,
    channel_map: Mapping[str, str] | None = None,
    channels: Sequence[str] | None = None,
    raw_channels: Sequence[str] = (),
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
        Channel names (after mapping) to read; ``None`` reads every signal whose physical dimension
        is a voltage (an amplifier's digital channels, such as a TMSi SAGA's STATUS and COUNTER, are
        left out) and the ``raw_channels``. All selected signals must share one sampling rate.
    raw_channels
        Channels (after mapping) kept in their file units whatever they are, such as a trigger input.
    """
    source = read_edf_source(path, channel_map=channel_map, channels=channels, raw_channels=raw_channels)
    return source.signal


def read_edf_source(
    path: str | Path,
    *,
    channel_map: Mapping[str, str] | None = None,
    channels: Sequence[str] | None = None,
    raw_channels: Sequence[str] = (),
) -> SourceRecording:
    """:func:`read_emg_edf`, with each voltage channel's digital codes and scaling
    (:class:`SourceChannel`)."""
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
    by_name = {
        mapping.get(signal.label, signal.label): signal
        for signal in recording.signals
        if signal.label not in ("EDF Annotations", "BDF Annotations")
    }
    if channels is None:
        names = [
            name
            for name, signal in by_name.items()
            if name in raw_channels or signal.physical_dimension.strip().lower() in _VOLT_SCALE
        ]
        names += [name for name in raw_channels if name not in names]
    else:
        names = list(channels)
    missing = [name for name in names if name not in by_name]
    if missing:
        raise RecordingError(f"{file.name} lacks channel(s) {missing}; it has {list(by_name)}")
    rates = {name: float(by_name[name].sampling_frequency) for name in names}
    if len(set(rates.values())) > 1:
        raise RecordingError(
            f"{file.name}: channels have different sampling rates {rates}; read them separately"
        )
    columns = []
    sources: dict[str, SourceChannel] = {}
    for name in names:
        signal = by_name[name]
        if name in raw_channels:
            columns.append(np.asarray(signal.data, dtype=np.float64))
            continue
        source = _edf_source(file, name, signal)
        sources[name] = source
        columns.append(source.volts())
    if not columns:
        raise RecordingError(f"{file.name} has no signals to read")
    rate_hz = next(iter(rates.values()))
    emg = EmgSignal(values=np.column_stack(columns), rate_hz=rate_hz, channels=tuple(names))
    return SourceRecording(signal=emg, sources=sources)


def _edf_source(file: Path, name: str, signal: Any) -> SourceChannel:
    """A voltage signal's digital codes and the header's scaling, in volts (EDF spec: physical =
    physical_min + (digital - digital_min) × (physical range / digital range))."""
    unit = signal.physical_dimension.strip().lower()
    if unit not in _VOLT_SCALE:
        raise RecordingError(
            f"{file.name}: channel {name!r} has physical dimension {signal.physical_dimension!r}, "
            f"expected one of V, mV, uV"
        )
    digital_range = float(signal.digital_max) - float(signal.digital_min)
    physical_range = float(signal.physical_max) - float(signal.physical_min)
    if not (digital_range > 0.0 and physical_range != 0.0):
        raise RecordingError(f"{file.name}: channel {name!r} has an empty physical or digital range")
    scale = _VOLT_SCALE[unit]
    gain = physical_range / digital_range
    offset = float(signal.physical_min) - float(signal.digital_min) * gain
    return SourceChannel(codes=np.asarray(signal.digital), gain_v=gain * scale, offset_v=offset * scale)


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
    source = read_csv_source(path, time_column=time_column, channels=channels, volts_per_unit=volts_per_unit)
    return source.signal


def read_csv_source(
    path: str | Path,
    *,
    time_column: str = TRIAL_TIME,
    channels: Sequence[str] | None = None,
    volts_per_unit: float = 1.0,
    raw_channels: Sequence[str] = (),
) -> SourceRecording:
    """:func:`read_emg_csv`, with each channel's numbers as parsed (float64, or int64 for a column of
    integers) and ``volts_per_unit``; ``raw_channels`` (a trigger) stay in the file's numbers."""
    file = Path(path)
    if not file.is_file():
        raise RecordingError(f"EMG file {file} does not exist")
    if not (math.isfinite(volts_per_unit) and volts_per_unit > 0.0):
        raise ParameterError(f"--csv-volts-per-unit must be positive, got {volts_per_unit}")
    try:
        frame = pd.read_csv(file)
    except (ValueError, OSError) as exc:
        raise RecordingError(f"{file.name} is not a readable CSV file: {exc}") from None
    signal = EmgSignal.from_frame(frame, channels=channels, time_column=time_column)
    sources = {
        name: SourceChannel(codes=_csv_numbers(frame[name]), gain_v=volts_per_unit)
        for name in signal.channels
        if name not in raw_channels
    }
    columns = [
        sources[name].volts() if name in sources else signal.values[:, i]
        for i, name in enumerate(signal.channels)
    ]
    values = np.column_stack(columns) if columns else signal.values
    return SourceRecording(signal=signal.with_values(values), sources=sources)


def _csv_numbers(column: pd.Series) -> NDArray[Any]:
    """A column's numbers as pandas parsed them: int64 for whole numbers, else float64."""
    values = column.to_numpy()
    return values if values.dtype == np.int64 else np.asarray(values, dtype=np.float64)
