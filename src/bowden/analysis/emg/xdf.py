"""XDF recordings (Lab Streaming Layer, LabRecorder): the EMG stream and bowden's markers.

Read with ``pyxdf`` (the ``emg`` extra), which puts every stream on the recorder's clock (its clock
offsets applied). The EMG stream is the one of type ``EMG`` (else the regular numeric stream with the
most channels); its per-sample time stamps are replaced by a least-squares line through them (the
stream is regular: the line is its true rate on the recorder's clock, free of the jitter of network
delivery). Markers are the string samples of bowden's marker stream (source id ``bowden-markers...``),
kept with their time stamps for the clock fit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bowden.analysis.emg.read import SourceChannel, volt_scale
from bowden.analysis.emg.signal import EmgSignal
from bowden.errors import RecordingError

MARKER_SOURCE_PREFIX = "bowden-markers"


@dataclass(frozen=True, kw_only=True)
class XdfRecording:
    """The EMG of an XDF file (file labels as channel names, volts) and bowden's markers in it."""

    emg: EmgSignal
    markers: tuple[tuple[float, str], ...]  # (recorder time s, marker text)
    stream_name: str
    # Per channel, the stream's samples in their own format (float32, double64, int) and unit factor.
    sources: dict[str, SourceChannel] = field(default_factory=dict)


def read_emg_xdf(path: str | Path) -> XdfRecording:
    """Read the EMG stream and bowden's marker stream of an XDF file (recorder clock, s)."""
    try:
        import pyxdf
    except ImportError:  # pragma: no cover - depends on the install
        raise RecordingError("reading XDF needs the 'emg' extra: pip install 'bowden[emg]'") from None
    file = Path(path)
    if not file.is_file():
        raise RecordingError(f"EMG file {file} does not exist")
    try:
        streams, _header = pyxdf.load_xdf(str(file), dejitter_timestamps=False)
    except Exception as exc:  # pyxdf raises bare Exceptions of many kinds on a damaged file
        raise RecordingError(f"{file.name} is not a readable XDF file: {exc}") from None
    numeric = [s for s in streams if _info(s, "channel_format") != "string" and _rate(s) > 0.0]
    emg_streams = [s for s in numeric if _info(s, "type").lower() == "emg"] or numeric
    if not emg_streams:
        raise RecordingError(f"{file.name} holds no regularly sampled stream (no EMG)")
    stream = max(emg_streams, key=lambda s: int(_info(s, "channel_count") or 0))
    name = _info(stream, "name") or "EMG"
    stamps = np.asarray(stream["time_stamps"], dtype=np.float64)
    samples = np.asarray(stream["time_series"])
    if samples.dtype == np.int8:  # the store keeps 16-bit and wider codes
        samples = samples.astype(np.int16)
    if samples.ndim != 2 or samples.dtype.kind not in "iuf":
        raise RecordingError(f"{file.name}: stream {name!r} does not hold numeric samples")
    if stamps.size < 2:
        raise RecordingError(f"{file.name}: stream {name!r} has {stamps.size} samples")
    # The rate of the stream on the recorder's clock: a line through all time stamps.
    index = np.arange(stamps.size, dtype=np.float64)
    i0, t0 = float(index.mean()), float(stamps.mean())
    slope = float(np.dot(index - i0, stamps - t0) / np.dot(index - i0, index - i0))
    labels, units = _channels(stream, samples.shape[1])
    sources = {
        label: SourceChannel(codes=np.ascontiguousarray(samples[:, i]), gain_v=_scale(unit))
        for i, (label, unit) in enumerate(zip(labels, units, strict=True))
    }
    emg = EmgSignal(
        values=np.column_stack([sources[label].volts() for label in labels]),
        rate_hz=1.0 / slope,
        channels=tuple(labels),
        start_s=t0 - slope * i0,
    )
    markers: list[tuple[float, str]] = []
    for s in streams:
        if _info(s, "channel_format") == "string" and _info(s, "source_id").startswith(MARKER_SOURCE_PREFIX):
            markers.extend(
                (float(t), str(v[0])) for t, v in zip(s["time_stamps"], s["time_series"], strict=True)
            )
    markers.sort(key=lambda m: m[0])
    return XdfRecording(emg=emg, markers=tuple(markers), stream_name=name, sources=sources)


def _scale(unit: str) -> float:
    """Volts per unit; no unit is µV (LSL amplifier apps' habit); a non-voltage channel stays as is."""
    try:
        return volt_scale(unit, default=1e-6)
    except RecordingError:
        return 1.0


def _info(stream: dict[str, Any], key: str) -> str:
    value = stream["info"].get(key, [""])
    return str(value[0] if isinstance(value, list) and value else value or "")


def _rate(stream: dict[str, Any]) -> float:
    try:
        return float(_info(stream, "nominal_srate") or 0.0)
    except ValueError:
        return 0.0


def _channels(stream: dict[str, Any], n: int) -> tuple[list[str], list[str]]:
    """Labels and units from the stream's ``desc/channels`` (XDF meta-data conventions)."""
    labels = [f"ch{i + 1}" for i in range(n)]
    units = [""] * n
    try:
        channels = stream["info"]["desc"][0]["channels"][0]["channel"]
    except (KeyError, IndexError, TypeError):
        return labels, units
    for i, channel in enumerate(channels[:n]):
        if isinstance(channel, dict):
            labels[i] = str((channel.get("label") or [labels[i]])[0])
            units[i] = str((channel.get("unit") or [""])[0] or "")
    return labels, units
