"""Which channel of an amplifier's file is which muscle: the label → muscle mapping.

A mapping file is a JSON object ``{"<file label>": "<muscle>", ...}`` whose muscles are those of
``bowden.contracts.MUSCLES``. :data:`SAGA_CHANNELS` is the example for a TMSi SAGA recording the eight
muscles on its first eight unipolar inputs (SAGA labels ``UNI1``..``UNI32``, ``BIP1``..``BIP4``,
``AUX``, ``TRIGGERS``, ``STATUS``, ``COUNTER``); ``--channels saga`` selects it. A lab that wires the
muscles elsewhere writes its own file (``docs/examples/saga_channels.json`` is this one).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Final

from bowden.analysis.emg.constants import BUILT_IN_MAPPINGS as BUILT_IN_MAPPINGS
from bowden.analysis.emg.constants import SAGA_CHANNELS as SAGA_CHANNELS
from bowden.analysis.emg.signal import EmgSignal
from bowden.contracts import MUSCLES
from bowden.errors import RecordingError

# The SAGA's digital input channel, where a trigger line from the controller is recorded.
SAGA_TRIGGER_CHANNEL: Final = "TRIGGERS"


def load_channel_map(source: str | Path) -> dict[str, str]:
    """A mapping file (JSON object label → muscle), or the name of a built-in mapping (``saga``).

    Raises
    ------
    RecordingError
        If the file cannot be read, is not a JSON object of strings, maps to a muscle bowden does
        not know, or maps two labels to one muscle.
    """
    if str(source) in BUILT_IN_MAPPINGS:
        return dict(BUILT_IN_MAPPINGS[str(source)])
    path = Path(source)
    try:
        content = json.loads(path.read_text(encoding="utf-8"))
    except OSError as error:
        raise RecordingError(f"channel map {path}: cannot be read ({error.strerror or error})") from None
    except json.JSONDecodeError as error:
        raise RecordingError(f"channel map {path}: not JSON ({error})") from None
    except UnicodeDecodeError:  # a binary file given by mistake (an EDF, a picture)
        raise RecordingError(f"channel map {path}: not JSON (not UTF-8 text)") from None
    if not isinstance(content, dict) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in content.items()
    ):
        raise RecordingError(f'channel map {path}: expected a JSON object {{"<file label>": "<muscle>"}}')
    unknown = sorted(v for v in content.values() if v not in MUSCLES)
    if unknown:
        raise RecordingError(
            f"channel map {path}: unknown muscle(s) {', '.join(unknown)} (known: {', '.join(MUSCLES)})"
        )
    if len(set(content.values())) != len(content):
        raise RecordingError(f"channel map {path}: two labels map to the same muscle")
    return dict(content)


def emg_map_channels(
    emg: EmgSignal, mapping: Mapping[str, str] | None, *, keep: Sequence[str] = ()
) -> EmgSignal:
    """The muscles of ``emg`` under their names (plus the ``keep`` channels, e.g. a trigger).

    Without a mapping the file's labels must already be muscle names. Other channels are dropped.

    Raises
    ------
    RecordingError
        Naming the labels of the mapping that the recording lacks, or — without a mapping — saying
        that no label is a muscle.
    """
    missing_keep = [name for name in keep if name not in emg.channels]
    if missing_keep:
        raise RecordingError(
            f"the recording has no channel {', '.join(map(repr, missing_keep))} "
            f"(its channels: {', '.join(emg.channels)})"
        )
    if mapping is None:
        muscles = [label for label in emg.channels if label in MUSCLES]
        if not muscles:
            raise RecordingError(
                f"unknown channel labels {', '.join(emg.channels)}: none is a muscle; give --channels MAP "
                "(a JSON file label → muscle, or 'saga')"
            )
        return emg.select([*muscles, *keep])
    absent = [label for label in mapping if label not in emg.channels]
    if absent:
        raise RecordingError(
            f"the channel map names label(s) {', '.join(absent)} that the recording lacks "
            f"(its channels: {', '.join(emg.channels)})"
        )
    labels = list(mapping)
    selected = emg.select([*labels, *keep])
    return selected.with_values(selected.values, [mapping[label] for label in labels] + list(keep))
