"""A trial's sEMG as an EDF+ or BDF+ file of the BIDS EMG datatype, its stored samples kept bit for bit.

The store keeps each muscle's EMG as stored values with a scaling, ``volts = stored × gain_v +
offset_v`` (:class:`bowden.store.emg_chunks.StoredEmgChannel`). The file holds them as its digital
samples (:mod:`bowden.share.emg_codes`: ``stored = code × code_step``, step 1 for integer codes):
16-bit codes go to EDF+, anything wider (24-bit codes, an XDF import's float32 counts) to BDF+ (BIDS
recommends BDF+, and allows both: bids-specification ``src/modality-specific-files/electromyography.md``,
"EMG data"). Each signal's physical range is the codes' digital range mapped through the step and
the store's scaling, so an EDF reader's ``(d − d_min)·(p_max − p_min)/(d_max − d_min) + p_min`` is
the store's formula.

The EDF header gives the physical range 8 ASCII characters each (EDF specification, "header record":
``8 ascii : physical minimum``), 6 significant digits with the sign: a reader of the file alone
gets the store's volts to within half a 16-bit step (0.23 steps at worst in the simulated study), so
rounding gives the codes back. The exact scaling is kept too: the ``gain_v``, ``offset_v`` and
``code_step`` columns of ``_channels.tsv`` (defined in its ``_channels.json``) give the store's
values bit for bit.

Records: an EDF file is a whole number of data records of equal duration, the duration stated in 8
characters (EDF specification, "8 ascii : duration of a data record, in seconds"). Where no record of
whole samples that the header states exactly divides the trial (a prime number of samples at 2048 Hz:
a record's duration is exact in 8 characters only for multiples of 32 samples), the last record is
padded with the last stored sample and the file becomes EDF+/BDF+ with an annotation
(EDF+ specification, section 2.2, "Time-stamped Annotations Lists") ``BAD_ACQ_SKIP`` over the
padding: the annotation MNE gives the gaps of a discontinuous EDF+ and MNE-BIDS keeps when it reads
the events (``mne_bids.config.ANNOTATIONS_TO_KEEP``), so ``raw.get_data(reject_by_annotation="omit")``
returns exactly the stored samples; ``_emg.json``'s ``RecordingDuration`` states the true length.
"""

from __future__ import annotations

import datetime as dt
import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from bowden.errors import StoreError
from bowden.share.emg_codes import FileCodes, file_codes
from bowden.store.emg_chunks import StoredEmgChannel

# Digital ranges of the two formats (EDF: 16-bit two's complement; BDF: 24-bit).
EDF_RANGE: Final = (-32768, 32767)
BDF_RANGE: Final = (-(2**23), 2**23 - 1)
# Units tried for the physical range, most significant digits in 8 characters wins.
_UNITS: Final = (("V", 1.0), ("mV", 1e3), ("uV", 1e6))  # the prefixes EDF readers (MNE) know
_HEADER_CHARS: Final = 8
# The annotation over a padded last record (MNE's name for samples that were not acquired).
PADDING_ANNOTATION: Final = "BAD_ACQ_SKIP"


@dataclass(frozen=True)
class EmgFileChannel:
    """What ``_channels.tsv`` says of one written signal."""

    name: str  # the EDF label (16 characters at most)
    muscle: str  # the store's name
    unit: str  # the file's physical dimension (``uV``)
    rate_hz: float
    gain_v: float
    offset_v: float
    stored_format: str = "int16"  # the store's values: int16, int32, float32, ...
    code_step: float = 1.0  # stored value = file code × code_step (in stored_format)
    exact: bool = True  # False: quantised to 24 bits, the exact values kept beside the file


@dataclass(frozen=True)
class EmgFile:
    """What :func:`write_emg_file` wrote: its signals, the stored samples and the padding after them."""

    channels: list[EmgFileChannel]
    samples: int
    padding: int
    rate_hz: float

    @property
    def duration_s(self) -> float:
        """The stored samples' duration (the padding excluded)."""
        return self.samples / self.rate_hz


def emg_extension(channels: Mapping[str, StoredEmgChannel]) -> str:
    """``.edf`` where every muscle's stored values are 16-bit integers, else ``.bdf`` (24-bit codes)."""
    narrow = all(
        channel.codes.dtype.kind in "iu"
        and (
            not channel.codes.size
            or (int(channel.codes.min()) >= EDF_RANGE[0] and int(channel.codes.max()) <= EDF_RANGE[1])
        )
        for channel in channels.values()
    )
    return ".edf" if narrow else ".bdf"


def write_emg_file(
    path: Path, channels: Mapping[str, StoredEmgChannel], *, start: dt.datetime | None
) -> EmgFile:
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
    per_record, duration = record_plan(length, rate)
    padding = -length % per_record
    signal_type: Any = edfio.BdfSignal if bdf else edfio.EdfSignal
    signals, described = [], []
    names = signal_labels(list(channels))
    for muscle, channel in channels.items():
        codes = file_codes(channel.codes, digital_range)
        unit, scale = _unit(channel, codes, digital_range)
        physical = tuple((d * codes.step * channel.gain_v + channel.offset_v) * scale for d in digital_range)
        digital = np.pad(codes.codes, (0, padding), mode="edge") if padding else codes.codes
        signals.append(
            signal_type.from_digital(
                digital.astype(np.int32 if bdf else np.int16),
                rate,
                label=names[muscle],
                transducer_type="sEMG electrode",
                physical_dimension=unit,
                physical_range=physical,
                digital_range=digital_range,
            )
        )
        described.append(
            EmgFileChannel(
                names[muscle], muscle, unit, rate, channel.gain_v, channel.offset_v,
                stored_format=str(channel.codes.dtype), code_step=codes.step, exact=codes.exact,
            )
        )
    file_type: Any = edfio.Bdf if bdf else edfio.Edf
    kwargs: dict[str, Any] = {"data_record_duration": duration}
    if padding:
        kwargs["annotations"] = [edfio.EdfAnnotation(length / rate, padding / rate, PADDING_ANNOTATION)]
    if start is not None:
        kwargs["recording"] = edfio.Recording(startdate=start.date())
        kwargs["starttime"] = start.time().replace(microsecond=0, tzinfo=None)
    file_type(signals, **kwargs).write(path)
    return EmgFile(described, samples=length, padding=padding, rate_hz=rate)


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
    """The rate the file states (an EDF rate is samples per record over the record's duration in 8
    characters): the store's where a record states it exactly; else the store's rounded to 1 mHz when
    within 1e-9 of it (1 / the median sample step of a simulated trial, 1999.9999999999982 Hz); else
    the nearest whole hertz (an import's rate measured on the host clock, 2048.0123 Hz: the amplifier's
    nominal rate, which the file's own clock keeps)."""
    nominal = round(stored_rate_hz, 3)
    if abs(nominal - stored_rate_hz) <= 1e-9 * stored_rate_hz and _exact_counts(nominal):
        return nominal
    if _exact_counts(stored_rate_hz):
        return stored_rate_hz
    return float(max(1, round(stored_rate_hz)))


def record_plan(samples: int, rate_hz: float) -> tuple[int, float]:
    """A data record's samples and duration: the first record of :func:`_exact_counts` (the longest up
    to 1 s whose duration the header's 8 characters state exactly) that divides the recording (no
    padding); where none divides it, the first of them (the last record then padded).

    Raises
    ------
    StoreError
        No record up to 10 s has a duration the header states exactly (a rate :func:`file_rate_hz`
        does not give).
    """
    counts = _exact_counts(rate_hz)
    if not counts:
        raise StoreError(f"no EDF data record of whole samples up to 10 s at {rate_hz} Hz states it exactly")
    per_record = next((count for count in counts if samples % count == 0 and count <= samples), counts[0])
    return per_record, per_record / rate_hz


@functools.cache
def _exact_counts(rate_hz: float) -> tuple[int, ...]:
    """Samples per record whose duration ``count / rate_hz`` is exact in the header's 8 characters:
    those up to 1 s longest first, then (a fractional rate, 2000.5 Hz: 4001 samples in 2 s) longer
    ones up to 10 s shortest first (the EDF specification asks for records under 61440 bytes)."""
    exact = []
    for count in range(1, max(1, int(10 * rate_hz)) + 1):
        duration = count / rate_hz
        text = repr(duration)
        if len(text) <= _HEADER_CHARS and float(text) * rate_hz == count:
            exact.append(count)
    within = [count for count in exact if count <= rate_hz]
    return (*within[::-1], *(count for count in exact if count > rate_hz))


def _unit(
    channel: StoredEmgChannel, codes: FileCodes, digital_range: tuple[int, int]
) -> tuple[str, float]:
    """The physical dimension whose 8-character range keeps the most digits of the scaling."""
    ends = [abs(d * codes.step * channel.gain_v + channel.offset_v) for d in digital_range]
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
