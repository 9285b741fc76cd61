"""EMG files: EDF/BDF and CSV recordings into an :class:`~bowden.analysis.emg.signal.EmgSignal` in volts.

EDF and BDF files are read with ``edfio`` (the ``emg`` extra: pure Python, maintained by MNE
developers); CSV files with pandas. XDF files (Lab Streaming Layer) are read by
:mod:`bowden.analysis.emg.xdf`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from bowden.analysis.emg.signal import EmgSignal
from bowden.contracts import TRIAL_TIME
from bowden.errors import ParameterError, RecordingError

# Physical dimensions found in EDF/BDF headers and their factor to volts.
_VOLT_SCALE = {"v": 1.0, "mv": 1e-3, "uv": 1e-6, "µv": 1e-6, "μv": 1e-6, "nv": 1e-9,
               # spelled out, as XDF's meta-data conventions write them
               "volts": 1.0, "millivolts": 1e-3, "microvolts": 1e-6, "nanovolts": 1e-9}


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
        Channel names (after mapping) to read; ``None`` reads all signals except EDF annotations.
        All selected signals must share one sampling rate.
    raw_channels
        Channels (after mapping) kept in their file units whatever they are, such as a trigger input.
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
        if name in raw_channels:
            columns.append(np.asarray(signal.data, dtype=np.float64))
            continue
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
