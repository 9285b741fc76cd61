"""``bowden emg import``: an amplifier's recording into the study store, on the controller's clock.

1. The recording is read (EDF/BDF with edfio, XDF with pyxdf, CSV with pandas) and its labels mapped
   to the muscles (:mod:`bowden.analysis.emg.channels`).
2. Its sync events are found: the pulses of a trigger channel (the line ``bowden run --trigger``
   raises at each trial's start and lowers at its end), matched to a run of consecutive trials by
   their timing; or bowden's LSL markers in an XDF file, matched by trial id.
3. One clock fit (offset and drift, least squares) over every event maps the recording onto the host
   clock of the trials' sync events; each trial's loop time is host time minus its zero.
4. Each matched trial's span is cut out, every channel checked (:func:`emg_check`), and all trials
   written in one transaction with their provenance.

Nothing is written unless every step succeeds for every trial. The same file imported again is a
no-op; another file for a trial that has EMG is refused unless ``replace``.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bowden.analysis.emg.channels import emg_map_channels
from bowden.analysis.emg.check import EmgCheckParameters, emg_check
from bowden.analysis.emg.read import SourceChannel, SourceRecording, read_csv_source, read_edf_source
from bowden.analysis.emg.signal import EmgSignal
from bowden.analysis.emg.sync import (
    DRIFT_TOLERANCE_PPM,
    RESIDUAL_TOLERANCE_S,
    ClockFit,
    TriggerPolarity,
    check_trigger_bit,
    clock_fit,
    match_pulses,
    trigger_pulses,
)
from bowden.analysis.emg.xdf import read_emg_xdf
from bowden.contracts import EMG_RATE_HZ, MUSCLES
from bowden.errors import BowdenError, ParameterError, RecordingError, StoreError, SyncError
from bowden.runtime.sync_events import MARKER_EDGES, parse_marker
from bowden.store.emg_chunks import EncodedEmgChunk, encode_verified_emg
from bowden.store.study_store import StudyStore
from bowden.study.emg.stored import TrialSync, emg_imports, trial_syncs, trials_with_emg, write_imported_emg

SUFFIXES = (".edf", ".bdf", ".xdf", ".csv")


@dataclass(frozen=True, kw_only=True)
class ImportOptions:
    """How ``bowden emg import`` reads and checks a recording (defaults: the paper's 2 kHz sEMG)."""

    trigger_channel: str | None = None
    trigger_polarity: TriggerPolarity = "auto"
    trigger_bit: int | None = None
    channel_map: Mapping[str, str] | None = None
    replace: bool = False
    drift_tolerance_ppm: float = DRIFT_TOLERANCE_PPM
    residual_tolerance_s: float = RESIDUAL_TOLERANCE_S
    expected_rate_hz: float = EMG_RATE_HZ
    csv_volts_per_unit: float = 1.0

    def __post_init__(self) -> None:
        # Checked here, when the options are made, so that a bad flag is refused before the store or
        # any recording is opened (the readers' and the fit's own checks came only after reading).
        # Each message names the flag and quotes the number in its unit (ms for the residual).
        positive = {
            "--rate": (self.expected_rate_hz, "a positive rate in Hz"),
            "--max-drift-ppm": (self.drift_tolerance_ppm, "positive"),
            "--max-residual-ms": (1e3 * self.residual_tolerance_s, "positive"),
            "--csv-volts-per-unit": (self.csv_volts_per_unit, "positive"),
        }
        for flag, (value, what) in positive.items():
            if not (math.isfinite(value) and value > 0.0):
                raise ParameterError(f"{flag} must be {what}, got {value:g}")
        if self.trigger_bit is not None:
            check_trigger_bit(self.trigger_bit)
        # Without a trigger channel nothing reads them (an XDF file is synchronised by bowden's LSL
        # markers): a flag the user gave must not be silently ignored.
        unread = [flag for flag, given in (("--trigger-bit", self.trigger_bit is not None),
                                           ("--trigger-polarity", self.trigger_polarity != "auto"))
                  if given]
        if unread and self.trigger_channel is None:
            verb = "reads" if len(unread) == 1 else "read"
            raise ParameterError(f"{' and '.join(unread)} {verb} the trigger channel: give "
                                 "--trigger-channel NAME too (without it an XDF recording is "
                                 "synchronised by bowden's LSL markers)")


@dataclass(frozen=True, kw_only=True)
class ImportResult:
    """What one file's import did: the trials written (empty for a no-op) and the clock fit."""

    file: Path
    sha256: str
    trials: tuple[int, ...]
    already_imported: tuple[int, ...]
    fit: ClockFit
    via: str  # "trigger" or "markers"

    def describe(self) -> str:
        done = f"imported EMG of trial(s) {_ids(self.trials)}" if self.trials else "nothing new to import"
        again = (
            f"; trial(s) {_ids(self.already_imported)} already from this file"
            if self.already_imported
            else ""
        )
        return f"{self.file.name}: {done}{again} (by {self.via}: {self.fit.describe()})"


@dataclass(frozen=True)
class _Recording:
    emg: EmgSignal  # muscles, recording clock, volts
    sources: Mapping[str, SourceChannel]  # per muscle, its samples as the file stores them
    events_s: np.ndarray  # recording times of the sync events
    controller_s: np.ndarray  # host times of the same events
    uncertainty_s: np.ndarray  # how long each event's send took on the host (the edge lies within)
    trials: tuple[int, ...]  # the trials the events cover
    via: str


def import_emg(
    store_path: str | Path, recording: str | Path, options: ImportOptions | None = None
) -> ImportResult:
    """Import one recording into the store (see the module docstring).

    Raises
    ------
    StoreError
        No store, or one without trials or without sync events.
    RecordingError
        The recording is unreadable, lacks or mislabels channels, covers no trial, or a channel fails
        :func:`emg_check` (names the trial and the channel).
    SyncError
        Trigger pulses that match no run of trials, drift or residuals beyond the tolerances.
    """
    options = options or ImportOptions()
    store_path, file = Path(store_path), Path(recording)
    if not store_path.is_file():
        raise StoreError(f"no study store at {store_path}")
    if file.suffix.lower() not in SUFFIXES:
        raise RecordingError(f"{file.name}: unknown recording type (expected {', '.join(SUFFIXES)})")
    if not file.is_file():
        raise RecordingError(f"EMG file {file} does not exist")
    digest = hashlib.sha256(file.read_bytes()).hexdigest()
    with StudyStore(store_path) as store:
        if not store.completed_trials():
            raise StoreError(f"{store_path} holds no completed trial to import EMG for")
        syncs = trial_syncs(store)
        if not syncs:
            raise StoreError(
                f"no trial in {store_path} has sync events: record trials with bowden run --trigger "
                "or --lsl so that a recording can be placed on their clock"
            )
        try:
            read = _read(file, options, syncs)
            fit = clock_fit(
                read.events_s,
                read.controller_s,
                drift_tolerance_ppm=options.drift_tolerance_ppm,
                residual_tolerance_s=options.residual_tolerance_s,
                uncertainty_s=read.uncertainty_s,
            )
        except (RecordingError, SyncError, ParameterError) as error:
            raise _naming(file, error) from None
        imports, has_emg = emg_imports(store), trials_with_emg(store)
        done = tuple(t for t in read.trials if imports.get(t, {}).get("sha256") == digest)
        todo = [t for t in read.trials if t not in done]
        taken = [t for t in todo if t in has_emg]
        if taken and not options.replace:
            sources = ", ".join(
                f"trial {t} from {imports[t].get('file', '?')}"
                if t in imports
                else f"trial {t} (stored with it)"
                for t in taken
            )
            raise RecordingError(
                f"{file.name}: EMG already stored for {sources}; give --replace to replace it"
            )
        chunks = {t: _trial_chunks(read, fit, syncs[t], options, file) for t in todo}
        provenance = {
            t: {
                "file": file.name,
                "sha256": digest,
                "via": read.via,
                "offset_s": fit.offset_s,
                "drift_ppm": fit.drift_ppm,
                "max_residual_s": fit.max_residual_s,
                "sync_events": fit.n_events,
                "max_edge_uncertainty_s": fit.max_uncertainty_s,
                "drift_resolved": fit.drift_resolved,
            }
            for t in todo
        }
        if chunks:
            write_imported_emg(store, chunks, provenance)
    return ImportResult(
        file=file, sha256=digest, trials=tuple(todo), already_imported=done, fit=fit, via=read.via
    )


def _read(file: Path, options: ImportOptions, syncs: Mapping[int, TrialSync]) -> _Recording:
    suffix = file.suffix.lower()
    trigger = options.trigger_channel
    mapping = options.channel_map
    if suffix == ".xdf":
        xdf = read_emg_xdf(file)
        source = SourceRecording(signal=xdf.emg, sources=xdf.sources)
        if trigger is None:
            emg, sources = _muscles(source, mapping, None)
            return _by_markers(file, emg, sources, xdf.markers, syncs)
        if trigger in xdf.sources:  # the trigger word as the stream holds it, not scaled as a voltage
            raw = xdf.sources[trigger].codes.astype(np.float64)
            index = xdf.emg.channels.index(trigger)
            values = np.array(xdf.emg.values)
            values[:, index] = raw
            source = SourceRecording(signal=xdf.emg.with_values(values), sources=xdf.sources)
        return _by_trigger(file, source, mapping, trigger, options, syncs)
    if trigger is None:
        raise ParameterError("give --trigger-channel NAME (the channel recording bowden's trigger)")
    if suffix in (".edf", ".bdf"):
        wanted = None if mapping is None else [*mapping, trigger]
        source = read_edf_source(file, channels=wanted, raw_channels=(trigger,))
    else:
        source = read_csv_source(file, volts_per_unit=options.csv_volts_per_unit, raw_channels=(trigger,))
    return _by_trigger(file, source, mapping, trigger, options, syncs)


def _muscles(
    source: SourceRecording, mapping: Mapping[str, str] | None, trigger: str | None
) -> tuple[EmgSignal, dict[str, SourceChannel]]:
    """The recording's muscles under their names (and the trigger channel), and each muscle's source."""
    keep = (trigger,) if trigger else ()
    emg = emg_map_channels(source.signal, mapping, keep=keep)
    label_of = {muscle: label for label, muscle in (mapping or {}).items()}
    sources = {
        muscle: source.sources[label_of.get(muscle, muscle)] for muscle in emg.channels if muscle not in keep
    }
    return emg, sources


def _by_trigger(
    file: Path,
    source: SourceRecording,
    mapping: Mapping[str, str] | None,
    trigger: str,
    options: ImportOptions,
    syncs: Mapping[int, TrialSync],
) -> _Recording:
    emg, sources = _muscles(source, mapping, trigger)
    pulses = trigger_pulses(emg, trigger, polarity=options.trigger_polarity, bit=options.trigger_bit)
    ids = list(syncs)
    hosts = np.array([[syncs[t].start.host_time_s, syncs[t].end.host_time_s] for t in ids])
    spreads = np.array([[syncs[t].start.uncertainty_s, syncs[t].end.uncertainty_s] for t in ids])
    first = match_pulses(
        pulses,
        hosts,
        ids,
        drift_tolerance_ppm=options.drift_tolerance_ppm,
        residual_tolerance_s=options.residual_tolerance_s,
        uncertainty_s=spreads,
    )
    n = len(pulses)
    muscles = emg.select([c for c in emg.channels if c != trigger])
    return _Recording(
        muscles,
        sources,
        pulses.ravel(),
        hosts[first : first + n].ravel(),
        spreads[first : first + n].ravel(),
        tuple(ids[first : first + n]),
        "trigger",
    )


def _by_markers(
    file: Path,
    emg: EmgSignal,
    sources: Mapping[str, SourceChannel],
    markers: tuple[tuple[float, str], ...],
    syncs: Mapping[int, TrialSync],
) -> _Recording:
    events, hosts, spreads, trials = [], [], [], []
    unknown: set[int] = set()
    for time_s, text in markers:
        fields = parse_marker(text)
        if fields is None or fields["event"] not in MARKER_EDGES:
            continue
        trial = fields.get("trial")
        if not isinstance(trial, int) or trial not in syncs:
            unknown.add(trial if isinstance(trial, int) else -1)
            continue
        sync = syncs[trial]
        edge = sync.start if MARKER_EDGES[fields["event"]] == "start" else sync.end
        events.append(time_s)
        hosts.append(edge.host_time_s)
        spreads.append(edge.uncertainty_s)
        if trial not in trials:
            trials.append(trial)
    if unknown:
        raise SyncError(
            f"its markers name trial(s) {_ids(sorted(unknown))} that the store has no sync "
            "events for (another study's store?)"
        )
    if not events:
        raise SyncError("no bowden trial marker in the recording (was the marker stream recorded?)")
    return _Recording(
        emg, sources, np.array(events), np.array(hosts), np.array(spreads), tuple(trials), "markers"
    )


def _trial_chunks(
    read: _Recording, fit: ClockFit, sync: TrialSync, options: ImportOptions, file: Path
) -> list[EncodedEmgChunk]:
    """The trial's span of the recording on its loop clock, checked, as verified store chunks of the
    file's own samples."""
    emg = read.emg
    # Loop time of recording sample i: fit(start + i / rate) - zero, a line in i.
    start = fit.offset_s + fit.slope * emg.start_s - sync.zero_host_time_s
    step = fit.slope / emg.rate_hz
    first = max(0, math.ceil(-start / step - 1e-9))
    last = min(emg.n_samples - 1, math.floor((sync.last_sample_s - start) / step + 1e-9))
    if last - first < 1:
        raise RecordingError(f"{file.name}: the recording covers no sample of trial {sync.trial_id}")
    segment = EmgSignal(
        values=emg.values[first : last + 1],
        rate_hz=1.0 / step,
        channels=emg.channels,
        start_s=start + first * step,
    )
    check = EmgCheckParameters(expected_channels=MUSCLES, expected_rate_hz=options.expected_rate_hz)
    try:
        emg_check(segment, check)
    except RecordingError as error:
        problems = str(error).replace("EMG recording unusable:\n  ", "").replace("\n  ", "; ")
        problems = problems.replace("expected_rate_hz", "--rate")
        raise RecordingError(f"{file.name}, trial {sync.trial_id}: {problems}") from None
    sources = {muscle: read.sources[muscle].select(first, last + 1) for muscle in MUSCLES}
    try:
        return encode_verified_emg(sources, start_time_s=segment.start_s, rate_hz=segment.rate_hz)
    except StoreError as error:
        raise StoreError(f"{file.name}, trial {sync.trial_id}: {error}") from None


def _naming(file: Path, error: BowdenError) -> BowdenError:
    """The error with the recording's name in front (several files may be imported at once)."""
    text = str(error)
    if text.startswith(file.name) or str(file) in text:
        return error
    return type(error)(f"{file.name}: {text}")


def _ids(ids: list[int] | tuple[int, ...]) -> str:
    return ", ".join(str(i) for i in ids)
