"""A 20-minute session with known truth: simulated trials, and the amplifier recording of their sEMG.

The trials are simulated (bowden.sim) and recorded through the real :class:`Recorder` with the two
sync events ``bowden run`` writes (host clock). The amplifier starts ``offset_s`` before the first
trial and its clock runs ``drift_ppm`` fast: its sample n is at host time
``start + n / (rate · (1 + drift))``. Each trial's simulated sEMG is laid sample by sample into the
recording where the trial ran, with low noise between trials; the truth is each sample's host time.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import edfio
import numpy as np
import pandas as pd

from bowden.contracts import MUSCLES, TRIAL_COLUMNS, TRIAL_TIME
from bowden.model import CompensationModel
from bowden.runtime.recorder import Recorder, TrialInfo
from bowden.runtime.sync_events import SYNC_KIND, SyncEvent
from bowden.sim import ProtocolSettings, generate_cohort
from bowden.sim.batch import simulate_trial
from bowden.store.study_store import StudyStore

RATE_HZ = 2000.0
SAGA_LABELS = tuple(f"UNI{i + 1}" for i in range(len(MUSCLES)))
TRIGGER = "TRIGGERS"
CONDITIONS = ("no_suit", "pretension", "support_50")
# Host times (s) of the trials' loop time zero: the first near the start, the last near the end of
# a 20-minute session.
TRIAL_ZEROS_S = (10_000.0, 10_590.0, 11_185.0)
START_EDGE_S = 0.0123  # loop time of the start edge (the trigger goes up just after the first cycle)
END_EDGE_DELAY_S = 0.037  # the end edge comes after the last cycle (the safe stop)


@dataclass
class Trial:
    trial_id: int
    info: TrialInfo
    samples: pd.DataFrame
    emg_v: np.ndarray  # simulated raw sEMG, samples x muscles, V
    zero_host_s: float

    @property
    def last_sample_s(self) -> float:
        return float(self.samples[TRIAL_TIME].iloc[-1])

    def edges_host_s(self) -> tuple[float, float]:
        return (self.zero_host_s + START_EDGE_S, self.zero_host_s + self.last_sample_s + END_EDGE_DELAY_S)


@dataclass
class Session:
    trials: list[Trial]
    store: Path  # trials with their sync events, no EMG (the lab's store after `bowden run`)
    offset_s: float
    drift_ppm: float
    first_zero_s: float = TRIAL_ZEROS_S[0]
    # emg_uv per seed and drift (tests change drift_ppm: the trials' spans and the length follow it): 20
    # minutes of 8 channels at 2 kHz, drawn once (every file written reads it).
    _emg_uv: dict[tuple[int, float], np.ndarray] = field(default_factory=dict, repr=False, compare=False)

    def host_time(self, n: np.ndarray) -> np.ndarray:
        """True host time of amplifier sample n, s."""
        start = self.first_zero_s - self.offset_s
        return start + np.asarray(n, dtype=np.float64) / (RATE_HZ * (1.0 + 1e-6 * self.drift_ppm))

    def amplifier_sample(self, host_s: float) -> float:
        """Amplifier sample position (fractional) of a host time."""
        start = self.first_zero_s - self.offset_s
        return (host_s - start) * RATE_HZ * (1.0 + 1e-6 * self.drift_ppm)

    @property
    def n_samples(self) -> int:
        end = self.amplifier_sample(self.trials[-1].edges_host_s()[1] + 6.0)
        return math.ceil(end / RATE_HZ) * int(RATE_HZ)  # whole 1 s EDF data records

    def trial_span(self, trial: Trial) -> np.ndarray:
        """The amplifier samples whose true loop time lies in the trial's [0, last cycle]."""
        first = math.floor(self.amplifier_sample(trial.zero_host_s)) - 2
        n = np.arange(first, first + len(trial.emg_v) + 10)
        t = self.host_time(n) - trial.zero_host_s
        return n[(t >= 0.0) & (t <= trial.last_sample_s)]

    def emg_uv(self, seed: int = 5) -> np.ndarray:
        """The recording's muscle channels, µV, samples x muscles: trials' sEMG and noise between.

        Drawn once per seed and drift, returned read-only (the same array to every caller)."""
        key = (seed, self.drift_ppm)
        if key not in self._emg_uv:
            rng = np.random.default_rng(seed)
            data = 3.0 * rng.standard_normal((self.n_samples, len(MUSCLES)))
            for trial in self.trials:
                span = self.trial_span(trial)
                assert len(span) <= len(trial.emg_v)
                data[span] = 1e6 * trial.emg_v[: len(span)]
            data.flags.writeable = False
            self._emg_uv[key] = data
        return self._emg_uv[key]

    def trigger(
        self, *, ramp_samples: float, pulses: Sequence[int] | None = None, late_s: Sequence[float] = ()
    ) -> np.ndarray:
        """The trigger input: high during each trial; edges ``ramp_samples`` wide (0: a hard step).

        ``pulses`` are the indices of the trials whose pulse the amplifier saw (default all);
        ``late_s[i]`` delays the end edge of trial i in the recording (a faulty line).
        """
        n = np.arange(self.n_samples, dtype=np.float64)
        line = np.zeros(self.n_samples)
        for index, trial in enumerate(self.trials):
            if pulses is not None and index not in pulses:
                continue
            start, end = trial.edges_host_s()
            end += late_s[index] if index < len(late_s) else 0.0
            rise, fall = self.amplifier_sample(start), self.amplifier_sample(end)
            if ramp_samples > 0.0:
                up = np.clip((n - rise) / ramp_samples + 0.5, 0.0, 1.0)
                down = np.clip((fall - n) / ramp_samples + 0.5, 0.0, 1.0)
                line = np.maximum(line, np.minimum(up, down))
            else:
                line[(n >= rise) & (n < fall)] = 1.0
        return line


def simulate_session(
    directory: Path,
    *,
    offset_s: float = 3.7,
    drift_ppm: float = 80.0,
    zeros_s: Sequence[float] = TRIAL_ZEROS_S,
) -> Session:
    """Three simulated trials recorded into ``directory/study.db`` with their sync events.

    ``zeros_s`` are the host times of the trials' loop time zero (default: a 20-minute session).
    """
    participant = generate_cohort(0)[0]
    model = CompensationModel.from_friction(k=0.1)
    store = directory / "study.db"
    trials = []
    for index, (condition, zero) in enumerate(zip(CONDITIONS, zeros_s, strict=True)):
        sim = simulate_trial(
            participant,
            condition,
            "V3",
            model=model,
            settings=ProtocolSettings(repetitions=3),
            seed=11 + index,
        )
        samples = sim.to_pandas().loc[:, list(TRIAL_COLUMNS)]
        info = TrialInfo(
            participant=participant.participant_id,
            condition=condition,
            speed="V3",
            metadata={"backend": "sim", "repetitions": sim.repetitions},
        )
        emg = sim.emg(RATE_HZ).loc[:, list(MUSCLES)].to_numpy()
        # The amplifier's fast clock fits a sample or two more into the trial: mirror the tail.
        emg = np.vstack([emg, emg[-10:][::-1]])
        trial = Trial(trial_id=0, info=info, samples=samples, emg_v=emg, zero_host_s=zero)
        trial.trial_id = _record(store, trial)
        trials.append(trial)
    return Session(
        trials=trials, store=store, offset_s=offset_s, drift_ppm=drift_ppm, first_zero_s=zeros_s[0]
    )


def _record(store: Path, trial: Trial) -> int:
    """The trial through the runtime's recorder, as `bowden run --record` stores it, with its edges."""
    with Recorder(store, trial.info, synchronous="NORMAL") as recorder:
        for row in trial.samples.itertuples(index=False, name=None):
            recorder.record(tuple(int(v) if i >= 10 else float(v) for i, v in enumerate(row)))
        for edge, host in zip(("start", "end"), trial.edges_host_s(), strict=True):
            event = SyncEvent(edge=edge, time_s=host - trial.zero_host_s, host_time_s=host, trigger="command")
            recorder.event(event.time_s, SYNC_KIND, event.message())
        assert recorder.trial_id is not None
        return recorder.trial_id


def write_edf(
    session: Session,
    path: Path,
    *,
    ramp_samples: float = 2.0,
    extra_labels: int = 2,
    pulses: Sequence[int] | None = None,
    late_s: Sequence[float] = (),
    flat: str | None = None,
) -> None:
    """An EDF like a SAGA's: UNI1..UNI8 the muscles (µV), spare UNI channels, and TRIGGERS.

    ``pulses`` and ``late_s`` as in :meth:`Session.trigger`; ``flat`` names a spare label recorded
    as zeros (a disconnected electrode).
    """
    emg = session.emg_uv()
    rng = np.random.default_rng(9)
    signals = [
        edfio.EdfSignal(
            emg[:, i], RATE_HZ, label=label, physical_dimension="uV", physical_range=(-2000.0, 2000.0)
        )
        for i, label in enumerate(SAGA_LABELS)
    ]
    for extra in range(extra_labels):
        label = f"UNI{len(SAGA_LABELS) + extra + 1}"
        signals.append(
            edfio.EdfSignal(
                np.zeros(len(emg)) if label == flat else 5.0 * rng.standard_normal(len(emg)),
                RATE_HZ,
                label=label,
                physical_dimension="uV",
                physical_range=(-2000.0, 2000.0),
            )
        )
    trigger = session.trigger(ramp_samples=ramp_samples, pulses=pulses, late_s=late_s)
    signals.append(edfio.EdfSignal(trigger, RATE_HZ, label=TRIGGER, physical_range=(0.0, 1.0)))
    edfio.Edf(signals, data_record_duration=1.0).write(path)


def direct_store(session: Session, path: Path, emg_v: np.ndarray) -> Path:
    """The same trials with the recording's samples stored directly at their true loop times."""
    with StudyStore(path) as store:
        for trial in session.trials:
            span = session.trial_span(trial)
            frame = pd.DataFrame(emg_v[span], columns=list(MUSCLES))
            frame.insert(0, TRIAL_TIME, session.host_time(span) - trial.zero_host_s)
            store.write_trial(trial.info, trial.samples, emg=frame)
    return path


def write_xdf(session: Session, path: Path, *, recorder_drift_ppm: float = 80.0) -> None:
    """An XDF as LabRecorder on a second PC writes it: the amplifier's EMG stream and bowden's markers.

    Every stream is on the recorder's clock, which runs ``recorder_drift_ppm`` fast against the
    controller host's and started elsewhere. The amplifier's samples are those of :meth:`Session.emg_uv`
    (their true host times), time-stamped on the recorder's clock; the markers are the texts bowden
    sends, stamped with the recorder's time of each trial edge.
    """
    from bowden.runtime.sync_events import MARKER_TRIAL_END, MARKER_TRIAL_START, marker_text

    from .xdf_writer import XdfWriter

    def recorder_clock(host_s: np.ndarray) -> np.ndarray:
        return 123.456 + (np.asarray(host_s) - session.first_zero_s) * (1.0 + 1e-6 * recorder_drift_ppm)

    writer = XdfWriter(path)
    writer.stream(
        1,
        name="SAGA",
        kind="EMG",
        source_id="saga-1005",
        channel_format="double64",
        nominal_srate=RATE_HZ,
        labels=SAGA_LABELS,
        unit="microvolts",
    )
    writer.stream(
        2,
        name="bowden markers",
        kind="Markers",
        source_id="bowden-markers-host",
        channel_format="string",
        nominal_srate=0.0,
        labels=("marker",),
    )
    emg = session.emg_uv()
    stamps = recorder_clock(session.host_time(np.arange(len(emg))))
    for start in range(0, len(emg), 20_000):
        writer.numeric_samples(1, stamps[start : start + 20_000], emg[start : start + 20_000])
    markers = []
    for trial in session.trials:
        for event, host in zip((MARKER_TRIAL_START, MARKER_TRIAL_END), trial.edges_host_s(), strict=True):
            text = marker_text(event, trial=trial.trial_id, time_s=host - trial.zero_host_s)
            markers.append((float(recorder_clock(np.array(host))), text))
    writer.string_samples(2, markers)
    for stream_id in (1, 2):
        writer.clock_offset(stream_id, float(stamps[0]), 0.0)
        writer.clock_offset(stream_id, float(stamps[-1]), 0.0)
    writer.close({1: len(emg), 2: len(markers)})


def write_csv(session: Session, path: Path) -> None:
    """A CSV export of an amplifier: its own time column (s), channels in µV, the trigger input."""
    emg = session.emg_uv()
    frame = pd.DataFrame(emg, columns=list(SAGA_LABELS))
    frame.insert(0, TRIAL_TIME, np.arange(len(emg)) / RATE_HZ)
    frame[TRIGGER] = session.trigger(ramp_samples=2.0)
    frame.to_csv(path, index=False, float_format="%.17g")


# A TMSi SAGA's 24-bit range: ±2^23 codes of 1/32 µV (the step the issue quotes for its BDF files).
SAGA_BDF_RANGE_UV = 262_144.0
TRIGGER_WORD_IDLE = 0xFFFF  # every bit of the SAGA's TRIGGER port reads 1 while nothing drives it


def saga_trigger_word(
    session: Session, *, bowden_bit: int | None, other_bit: int | None = None, other_pulses: int = 0
) -> np.ndarray:
    """The SAGA's TRIGGERS channel: negative logic, so a driven bit reads 0 (TMSi knowledge base,
    "How can I send triggers to SAGA via USB ports?").

    ``bowden_bit`` is the bit bowden's line drives (None: the channel is that one line, 1 idle, 0
    during a trial); ``other_bit`` a bit another device (a stimulus PC) pulses ``other_pulses``
    times, 50 ms each, spread over the recording and some inside trials.
    """
    line = session.trigger(ramp_samples=0.0)  # 1 during a trial: the driven state
    if bowden_bit is None:
        return 1.0 - line
    word = np.full(session.n_samples, TRIGGER_WORD_IDLE, dtype=np.int64)
    word[line > 0.5] &= ~(1 << bowden_bit)
    if other_bit is not None and other_pulses:
        starts = np.linspace(0.02, 0.95, other_pulses) * session.n_samples
        for start in starts.astype(np.int64):
            word[start : start + int(0.05 * RATE_HZ)] &= ~(1 << other_bit)
    return word.astype(np.float64)


def write_saga_file(
    session: Session,
    path: Path,
    *,
    bowden_bit: int | None,
    other_bit: int | None = None,
    other_pulses: int = 0,
    artefact_uv: float = 0.0,
) -> None:
    """A SAGA recording as its EDF/BDF exports lay it out (by the suffix of ``path``).

    UNI1..UNI8 the muscles, one spare UNI, then the digital channels with an empty physical dimension:
    TRIGGERS (the trigger word, 0..max as TMSi's Poly5-to-EDF converter scales it), STATUS and
    COUNTER. A BDF keeps 24-bit codes of 1/32 µV; ``artefact_uv`` adds one spike of that size to
    UNI1 at 10 % of the recording (a movement artefact that fixes a per-trial int16 range).
    """
    bdf = path.suffix.lower() == ".bdf"
    signal_type = edfio.BdfSignal if bdf else edfio.EdfSignal
    digital = (-(2**23), 2**23 - 1) if bdf else (-(2**15), 2**15 - 1)
    physical = (-SAGA_BDF_RANGE_UV, SAGA_BDF_RANGE_UV) if bdf else (-2000.0, 2000.0)
    emg = session.emg_uv()
    if artefact_uv:
        emg = emg.copy()  # the session's array is every file's
        emg[session.n_samples // 10, 0] += artefact_uv
    labels = (*SAGA_LABELS, f"UNI{len(SAGA_LABELS) + 1}")
    spare = 5.0 * np.random.default_rng(9).standard_normal(len(emg))
    signals = [
        signal_type(
            emg[:, i] if i < emg.shape[1] else spare,
            RATE_HZ,
            label=label,
            physical_dimension="uV",
            physical_range=physical,
            digital_range=digital,
        )
        for i, label in enumerate(labels)
    ]
    word = saga_trigger_word(session, bowden_bit=bowden_bit, other_bit=other_bit, other_pulses=other_pulses)
    counter = np.arange(len(emg)) % int(RATE_HZ)
    for label, values, top in (
        (TRIGGER, word, float(word.max())),
        ("STATUS", np.zeros(len(emg)), 100.0),
        ("COUNTER", counter.astype(np.float64), RATE_HZ),
    ):
        signals.append(
            signal_type(values, RATE_HZ, label=label, physical_range=(0.0, top), digital_range=digital)
        )
    (edfio.Bdf if bdf else edfio.Edf)(signals, data_record_duration=1.0).write(path)
