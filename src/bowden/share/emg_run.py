"""One trial's sEMG in the export: the EDF/BDF file, its sidecars, and the exact values it cannot hold.

The file (:mod:`bowden.share.emg_file`) keeps the stored samples bit for bit wherever 24 bits can
(:mod:`bowden.share.emg_codes`). A channel whose stored floats no 24-bit step reproduces is written
quantised to 24 bits (what an EDF/BDF reader can use), and its stored values go, exactly, to
``sourcedata/sub-<p>/[ses-<s>/]emg/<stem>_emg-exact.tsv.gz`` (BIDS leaves ``sourcedata/`` free of
rules: bids-specification ``src/common-principles.md``, "Source vs. raw vs. derived data"): one
column per muscle, shortest round-trip decimals of each stored value. The ``_channels.tsv`` column
``exact_values`` names that file for those channels. Nothing stored is refused or lost.
"""

from __future__ import annotations

import datetime as dt
import gzip
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bowden.share import layout
from bowden.share.emg_file import EmgFile, emg_extension, write_emg_file
from bowden.share.emg_sidecars import CHANNELS_SIDECAR, channels_table, emg_sidecar
from bowden.store.emg_chunks import StoredEmgChannel


@dataclass(frozen=True, kw_only=True)
class EmgRunFacts:
    """What the EMG's sidecar states beyond the file: mains, simulated, the amplifier's maker."""

    power_line_hz: float | None
    simulated: bool
    manufacturer: str | None


def write_emg_run(
    root: Path,
    folder: Path,
    stem: str,
    channels: Mapping[str, StoredEmgChannel],
    *,
    start: dt.datetime | None,
    facts: EmgRunFacts,
) -> tuple[Path, EmgFile]:
    """Write ``<stem>_emg.edf|.bdf`` with ``_emg.json`` and ``_channels.tsv/.json`` into ``folder``
    (inside the dataset ``root``); returns the EMG file's path and what it holds."""
    path = folder / f"{stem}_emg{emg_extension(channels)}"
    written = write_emg_file(path, channels, start=start)
    exact_name = None
    if not all(channel.exact for channel in written.channels):
        exact = root / "sourcedata" / folder.relative_to(root) / f"{stem}_emg-exact.tsv.gz"
        _write_exact_values(exact, channels)
        exact_name = exact.relative_to(root).as_posix()
    layout.write_json(
        folder / f"{stem}_emg.json",
        emg_sidecar(
            written.channels,
            task=layout.TASK,
            duration_s=written.duration_s,
            power_line_hz=facts.power_line_hz,
            simulated=facts.simulated,
            manufacturer=facts.manufacturer,
        ),
    )
    layout.write_table(folder / f"{stem}_channels.tsv", channels_table(written.channels, exact_name))
    layout.write_json(folder / f"{stem}_channels.json", CHANNELS_SIDECAR)
    return path, written


def _write_exact_values(path: Path, channels: Mapping[str, StoredEmgChannel]) -> None:
    """Every muscle's stored values as shortest round-trip text (a header row of muscle names)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    columns = [
        [repr(float(v)) if channel.codes.dtype.kind == "f" else str(int(v)) for v in channel.codes]
        for channel in channels.values()
    ]
    text = "\t".join(channels) + "\n" + "".join("\t".join(row) + "\n" for row in zip(*columns, strict=True))
    with path.open("wb") as raw, gzip.GzipFile(filename="", fileobj=raw, mode="wb", mtime=0) as out:
        out.write(text.encode())


def exact_values(path: Path) -> dict[str, np.ndarray[Any, Any]]:
    """The stored values of :func:`_write_exact_values`'s file, as float64 (for readers and tests)."""
    with gzip.open(path, "rt") as text:
        header = text.readline().rstrip("\n").split("\t")
        rows = [line.rstrip("\n").split("\t") for line in text]
    return {name: np.array([float(row[i]) for row in rows]) for i, name in enumerate(header)}
