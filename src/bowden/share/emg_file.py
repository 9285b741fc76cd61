"""A trial's sEMG as an EDF+ or BDF+ file of the BIDS EMG datatype, its stored codes kept bit for bit.

The store keeps each muscle's EMG as integer codes with a scaling, ``volts = codes × gain_v + offset_v``
(:class:`bowden.store.emg_chunks.StoredEmgChannel`). The file holds those codes as its digital samples:
16-bit codes go to EDF+, wider integer codes that fit 24 bits to BDF+ (BIDS recommends BDF+, and
allows both: bids-specification ``src/modality-specific-files/electromyography.md``, "EMG data").
Each signal's physical range is the codes' digital range mapped through the store's scaling, so an
EDF reader's ``(d − d_min)·(p_max − p_min)/(d_max − d_min) + p_min`` is the store's formula.

The EDF header gives the physical range 8 ASCII characters each (EDF specification, "header record":
``8 ascii : physical minimum``), 6 significant digits with the sign: a reader of the file alone
gets the store's volts to within half a 16-bit step (0.23 steps at worst in the simulated study), so
rounding gives the codes back. The exact scaling is kept too: the
``gain_v`` and ``offset_v`` columns of ``_channels.tsv`` (defined in its ``_channels.json``) give
``codes × gain_v + offset_v``, the store's float64 volts bit for bit.

Codes that are not integers (an XDF import's float32 stream) have no lossless EDF/BDF form; such a
trial is refused with a :class:`~bowden.errors.StoreError` naming it, rather than written rounded.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from bowden.errors import StoreError
from bowden.store.emg_chunks import StoredEmgChannel

# Digital ranges of the two formats (EDF: 16-bit two's complement; BDF: 24-bit).
EDF_RANGE: Final = (-32768, 32767)
BDF_RANGE: Final = (-(2**23), 2**23 - 1)
# Units tried for the physical range, most significant digits in 8 characters wins.
_UNITS: Final = (("V", 1.0), ("mV", 1e3), ("uV", 1e6))  # the prefixes EDF readers (MNE) know
_HEADER_CHARS: Final = 8


@dataclass(frozen=True)
class EmgFileChannel:
    """What ``_channels.tsv`` says of one written signal."""

    name: str  # the EDF label (16 characters at most)
    muscle: str  # the store's name
    unit: str  # the file's physical dimension (``uV``)
    rate_hz: float
    gain_v: float
    offset_v: float


def emg_extension(channels: Mapping[str, StoredEmgChannel]) -> str:
    """``.edf`` for 16-bit codes, ``.bdf`` for integer codes within 24 bits.

    Raises
    ------
    StoreError
        Codes that are not integers, or wider than 24 bits (names the muscle).
    """
    wide = False
    for muscle, channel in channels.items():
        codes = channel.codes
        if codes.dtype.kind not in "iu":
            raise StoreError(
                f"the EMG of {muscle!r} is stored as {codes.dtype} values, not integer codes: EDF and BDF "
                "cannot hold it without rounding"
            )
        if codes.size and (int(codes.min()) < BDF_RANGE[0] or int(codes.max()) > BDF_RANGE[1]):
            raise StoreError(f"the EMG codes of {muscle!r} exceed 24 bits: BDF cannot hold them")
        wide = wide or codes.dtype.itemsize > 2
    return ".bdf" if wide else ".edf"


def write_emg_file(
    path: Path, channels: Mapping[str, StoredEmgChannel], *, start: dt.datetime | None
) -> list[EmgFileChannel]:
    """Write the channels (equal rates and lengths, as the store keeps a trial's) to ``path``.

    ``path`` ends in the extension :func:`emg_extension` gives. ``start`` is the recording's start
    (the trial's ``started_utc``), None for the EDF's default date.
    """
    import edfio

    bdf = path.suffix == ".bdf"
    digital_range = BDF_RANGE if bdf else EDF_RANGE
    rates = {channel.rate_hz for channel in channels.values()}
    lengths = {channel.codes.size for channel in channels.values()}
    if len(rates) != 1 or len(lengths) != 1:
        raise StoreError(f"{path.name}: the muscles' EMG differ in rate or length ({rates}, {lengths})")
    rate, length = file_rate_hz(rates.pop()), lengths.pop()
    signal_type: Any = edfio.BdfSignal if bdf else edfio.EdfSignal
    signals, described = [], []
    names = signal_labels(list(channels))
    for muscle, channel in channels.items():
        unit, scale = _unit(channel, digital_range)
        physical = tuple((d * channel.gain_v + channel.offset_v) * scale for d in digital_range)
        signals.append(
            signal_type.from_digital(
                channel.codes.astype(np.int32 if bdf else np.int16),
                rate,
                label=names[muscle],
                transducer_type="sEMG electrode",
                physical_dimension=unit,
                physical_range=physical,
                digital_range=digital_range,
            )
        )
        described.append(EmgFileChannel(names[muscle], muscle, unit, rate, channel.gain_v, channel.offset_v))
    file_type: Any = edfio.Bdf if bdf else edfio.Edf
    kwargs: dict[str, Any] = {"data_record_duration": _record_duration(length, rate)}
    if start is not None:
        kwargs["recording"] = edfio.Recording(startdate=start.date())
        kwargs["starttime"] = start.time().replace(microsecond=0, tzinfo=None)
    file_type(signals, **kwargs).write(path)
    return described


# EDF labels are 16 characters (EDF specification, "16 ascii : label"); the paper's longest muscle.
_SHORT_LABELS: Final = {"posterior_deltoid": "post_deltoid"}
_LABEL_CHARS: Final = 16


def signal_labels(muscles: list[str]) -> dict[str, str]:
    """Each muscle's EDF label: its name, shortened to 16 characters where longer.

    Raises
    ------
    StoreError
        Two muscles whose labels would be equal.
    """
    labels = {m: _SHORT_LABELS.get(m, m)[:_LABEL_CHARS] for m in muscles}
    if len(set(labels.values())) < len(labels):
        raise StoreError(f"the EMG channels {muscles} do not have distinct 16-character EDF labels")
    return labels


def file_rate_hz(stored_rate_hz: float) -> float:
    """The rate the file states: the store's (1 / the median sample step, e.g. 1999.9999999999982 Hz)
    rounded to 1 mHz when within 1e-9 of it, since an EDF rate is samples per record over the record's
    duration in 8 characters."""
    nominal = round(stored_rate_hz, 3)
    return nominal if abs(nominal - stored_rate_hz) <= 1e-9 * stored_rate_hz else stored_rate_hz


def _unit(channel: StoredEmgChannel, digital_range: tuple[int, int]) -> tuple[str, float]:
    """The physical dimension whose 8-character range keeps the most digits of the scaling."""
    ends = [abs(d * channel.gain_v + channel.offset_v) for d in digital_range]
    best, best_error = _UNITS[0], math.inf
    for unit, scale in _UNITS:
        largest = max(ends) * scale
        if largest >= 10 ** (_HEADER_CHARS - 2):  # "-" and at least one digit after the point
            continue
        integer_digits = max(1, len(str(int(largest))))
        error = 10.0 ** -(_HEADER_CHARS - 2 - integer_digits) / max(largest, 1e-300)
        if error < best_error:
            best, best_error = (unit, scale), error
    return best


def _record_duration(samples: int, rate_hz: float) -> float:
    """A data record's duration: the longest up to 1 s that divides the recording into whole records
    (EDF files hold whole records; padding would add samples the store does not hold) and that the
    header's 8 characters give exactly."""
    per_second = max(1, int(rate_hz))
    for count in range(min(samples, per_second), 0, -1):
        if samples % count:
            continue
        duration = count / rate_hz
        text = repr(duration)
        if len(text) <= _HEADER_CHARS and float(text) * rate_hz == count:
            return duration
    raise StoreError(
        f"no EDF data record of whole samples fits {samples} samples at {rate_hz} Hz with a duration the "
        "header states exactly: the EMG would have to be padded or cut"
    )
