"""The EMG file's sidecars: ``_emg.json`` and ``_channels.tsv`` / ``_channels.json``.

Required ``_emg.json`` fields (bids-specification ``src/schema/rules/sidecars/emg.yaml``,
``EMGRequired``): ``EMGPlacementScheme``, ``EMGReference``, ``SamplingFrequency``,
``PowerLineFrequency``, ``RecordingType``, ``SoftwareFilters``. ``_channels.tsv`` requires ``name``,
``type``, ``units`` and recommends ``target_muscle``, ``placement_scheme`` (``measured`` or
``other``), ``reference``
(``src/schema/rules/tabular_data/emg.yaml``, ``EMGChannels``); columns of our own are allowed when the
``_channels.json`` defines them (``additional_columns: allowed_if_defined``): ``muscle`` (the store's
name), ``gain_v`` and ``offset_v``, the store's exact scaling of the file's codes.

The placement is the paper's: electrodes on the muscles per the SENIAM recommendations
(paper, Methods: "following the international SENIAM recommendations \\citep{Hermens1999}").
The stored sEMG is raw: no software filter ran on it (the analysis filters 20–400 Hz later, on its
own copy).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Final

import pandas as pd

from bowden.share.emg_file import EmgFileChannel

MUSCLE_NAMES: Final = {
    "anterior_deltoid": "anterior deltoid",
    "medial_deltoid": "medial deltoid",
    "posterior_deltoid": "posterior deltoid",
    "biceps": "biceps brachii",
    "triceps": "triceps brachii",
    "trapezius": "upper trapezius",
    "latissimus_dorsi": "latissimus dorsi",
    "pectoralis_major": "pectoralis major",
}

CHANNELS_SIDECAR: Final[dict[str, Any]] = {
    "muscle": {
        "Description": "The muscle's name in the bowden store (the EDF label is at most 16 characters)."
    },
    "gain_v": {
        "Description": "The store's scaling of this channel's digital samples: "
        "volts = code * gain_v + offset_v (the EDF header's physical range gives it to 8 "
        "characters; this column exactly).",
        "Units": "V",
    },
    "offset_v": {"Description": "Offset of the scaling (see gain_v).", "Units": "V"},
    "stored_format": {
        "Description": "How the bowden store keeps this channel's values: int16 or int32 codes, or "
        "float32/float64 values (an XDF import)."
    },
    "code_step": {
        "Description": "The store's value of one digital step of the file: stored value = digital "
        "sample * code_step, rounded to stored_format (bit for bit; 1: the digital samples are the "
        "stored codes). Then volts = stored value * gain_v + offset_v."
    },
    "exact_values": {
        "Description": "n/a: the file's digital samples give the stored values bit for bit. Else the "
        "file under sourcedata/ that holds the stored values exactly (the file holds them quantised "
        "to 24 bits, which no 24-bit step reproduces)."
    },
}


def channels_table(channels: Sequence[EmgFileChannel], exact_values: str | None = None) -> pd.DataFrame:
    """``_channels.tsv``: one row per signal of the file, in the file's order; ``exact_values`` names
    the file that keeps the stored values of the channels the EMG file could not hold exactly."""
    return pd.DataFrame(
        {
            "name": [c.name for c in channels],
            "type": ["EMG"] * len(channels),
            "units": [c.unit for c in channels],
            "target_muscle": [MUSCLE_NAMES.get(c.muscle, c.muscle.replace("_", " ")) for c in channels],
            "placement_scheme": ["other"] * len(channels),
            "placement_description": ["SENIAM recommendations (Hermens et al., 1999)"] * len(channels),
            "reference": ["bipolar"] * len(channels),
            "sampling_frequency": [c.rate_hz for c in channels],
            "low_cutoff": ["n/a"] * len(channels),
            "high_cutoff": ["n/a"] * len(channels),
            "muscle": [c.muscle for c in channels],
            "gain_v": [repr(c.gain_v) for c in channels],
            "offset_v": [repr(c.offset_v) for c in channels],
            "stored_format": [c.stored_format for c in channels],
            "code_step": [repr(c.code_step) for c in channels],
            "exact_values": [None if c.exact else exact_values for c in channels],
        }
    )


def emg_sidecar(
    channels: Sequence[EmgFileChannel],
    *,
    task: str,
    duration_s: float,
    power_line_hz: float | None,
    simulated: bool,
    manufacturer: str | None = None,
) -> dict[str, Any]:
    """``_emg.json`` of one trial's EMG file; ``RecordingDuration`` is the stored samples' (a padded
    last record excluded); ``Manufacturer`` the amplifier's maker where known (RECOMMENDED)."""
    sidecar: dict[str, Any] = {
        "TaskName": task,
        "TaskDescription": "raise and lower the arm following a reference shown on a display, with the "
        "exosuit in the trial's condition (see the events)",
        "EMGPlacementScheme": "Other",
        "EMGPlacementSchemeDescription": "bipolar surface electrodes on each muscle following the SENIAM "
        "recommendations (Hermens et al., 1999)",
        "EMGReference": "bipolar: each channel is the difference of its electrode pair",
        "SamplingFrequency": channels[0].rate_hz,
        "PowerLineFrequency": power_line_hz if power_line_hz is not None else "n/a",
        "RecordingType": "continuous",
        "RecordingDuration": duration_s,
        "SoftwareFilters": "n/a",
        "EMGChannelCount": len(channels),
    }
    if simulated:
        sidecar["Manufacturer"] = "none: sEMG synthesised by bowden.sim"
    elif manufacturer:
        sidecar["Manufacturer"] = manufacturer
    return sidecar
