"""``bowden study``: the paper end to end on the simulated suit, stage by stage, resumable.

Stages, each writing into the study directory:

1. **bench** — the mannequin identification protocol on the simulated bench → ``bench.parquet``;
2. **identify** — the robust fit per direction → ``model.json`` (and the identification figure);
3. **cohort** — virtual participants drawn like the paper's → the store's ``participants``;
4. **trials** — each participant: no suit first, the other conditions in a seeded random order, three
   speeds, ten repetitions, the identified model in the controller → ``study.db`` (samples, EMG,
   questionnaires). A trial already in the store is skipped, so an interrupted run resumes;
5. **analysis**, **statistics** and **report** — as ``bowden analyze`` does for a real study.

``--force`` starts again from an empty directory's worth of results.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path

from bowden import __version__
from bowden import contracts as c
from bowden.errors import ParameterError
from bowden.identify import TransmissionIdentifier
from bowden.model import CompensationModel
from bowden.runtime.recorder import TrialInfo
from bowden.sim.batch import ProtocolSettings, condition_order, simulate_trial, trial_seed
from bowden.sim.bench import BenchProtocol, run_bench
from bowden.sim.parameters import check_seed
from bowden.sim.participants import VirtualParticipant, generate_cohort
from bowden.sim.questionnaires import questionnaire_answers
from bowden.sim.results import TrialSimulation
from bowden.study.analyze import AnalysisReport, analyze_store
from bowden.study.progress import StageProgress
from bowden.study.store import StudyStore

# A bench protocol a tenth the size of the paper's (2 loads × 4 speeds × 2 repetitions) for quick runs.
QUICK_BENCH = BenchProtocol(spool_speeds_rad_s=(0.5, 1.0, 3.0, 6.0), loads_nm=(1.0, 3.0), repetitions=2)


@dataclass(frozen=True, kw_only=True)
class StudySettings:
    """What ``bowden study`` simulates.

    Parameters
    ----------
    participants
        Size of the virtual cohort (paper: 17).
    seed
        Seed of everything random: bench noise, cohort, condition orders, trial noise.
    repetitions
        Raise-and-lower cycles per trial (paper: 10; the analysis drops the first unless it is the only
        one).
    quick_bench
        Use a reduced bench protocol (for tests and demonstrations) instead of the paper's.
    store_emg
        Keep the raw 2 kHz sEMG of every trial in the store (16-bit, as EDF files do).
    """

    participants: int = 17
    seed: int = 0
    repetitions: int = c.REPETITIONS_PER_TRIAL
    quick_bench: bool = False
    store_emg: bool = True

    def __post_init__(self) -> None:
        if not 2 <= self.participants <= 200:
            raise ParameterError(f"participants must be between 2 and 200, got {self.participants}")
        if not 1 <= self.repetitions <= 50:
            raise ParameterError(f"repetitions must be between 1 and 50, got {self.repetitions}")
        check_seed(self.seed)


@dataclass
class StudyResult:
    """Where everything went, and how long each stage took (s)."""

    directory: Path
    report: Path
    store: Path
    model: Path
    trials_simulated: int
    trials_skipped: int
    stage_seconds: dict[str, float] = field(default_factory=dict)
    analysis: AnalysisReport | None = None


class _Timer:
    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        start = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - start


def run_study(
    settings: StudySettings,
    directory: str | Path,
    *,
    force: bool = False,
    progress: StageProgress | None = None,
) -> StudyResult:
    """Run (or resume) the simulated study in ``directory`` and write its report."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    progress = progress if progress is not None else StageProgress(enabled=False)
    timer = _Timer()
    settings_file = out / "settings.json"
    if force:
        for name in (
            "bench.parquet",
            "model.json",
            "study.db",
            "study.db-wal",
            "study.db-shm",
            "report.html",
        ):
            (out / name).unlink(missing_ok=True)
    elif settings_file.exists() and json.loads(settings_file.read_text()) != asdict(settings):
        raise ParameterError(
            f"{out} holds a study run with other settings ({settings_file}); "
            "use another --out directory or --force to start again"
        )
    settings_file.write_text(json.dumps(asdict(settings), indent=2) + "\n")

    with timer.stage("bench"):
        bench_path = _bench_stage(settings, out, progress)
    with timer.stage("identify"):
        model_path = out / "model.json"
        if not model_path.exists():
            with progress.spinner("identifying the transmission"):
                identifier = TransmissionIdentifier().fit(bench_path)
            identifier.model_.save(model_path)
        model = CompensationModel.load(model_path)

    store_path = out / "study.db"
    with StudyStore(store_path) as store:
        store.discard_unfinished_trials()
        store.put_artifact("model.json", model_path.read_text())
        store.put_artifact("settings.json", settings_file.read_text())
        with timer.stage("cohort"):
            # The paper's 12 women in 17, kept in proportion for other cohort sizes.
            cohort = generate_cohort(settings.seed, n_participants=settings.participants)
            for participant in cohort:
                store.add_participant(
                    participant.participant_id, participant.subject, {"age_years": participant.age_years}
                )
        with timer.stage("trials"):
            simulated, skipped = _trials_stage(settings, cohort, model, store, progress)

    with timer.stage("analysis, statistics and report"):
        analysis = analyze_store(
            store_path,
            out / "report.html",
            simulated=True,
            bench_path=bench_path,
            progress=progress,
            timings=timer.seconds,
        )
    return StudyResult(
        directory=out,
        report=out / "report.html",
        store=store_path,
        model=model_path,
        trials_simulated=simulated,
        trials_skipped=skipped,
        stage_seconds=timer.seconds,
        analysis=analysis,
    )


def _bench_stage(settings: StudySettings, out: Path, progress: StageProgress) -> Path:
    path = out / "bench.parquet"
    if path.exists():
        return path
    protocol = QUICK_BENCH if settings.quick_bench else BenchProtocol()
    with progress.bar("simulating the mannequin bench", protocol.n_strokes) as advance:
        frame = run_bench(protocol=protocol, seed=settings.seed, progress=lambda done, _total: advance(done))
    tmp = path.with_suffix(".parquet.tmp")
    frame.to_parquet(tmp, index=False)
    tmp.replace(path)
    return path


def _trials_stage(
    settings: StudySettings,
    cohort: tuple[VirtualParticipant, ...],
    model: CompensationModel,
    store: StudyStore,
    progress: StageProgress,
) -> tuple[int, int]:
    protocol = ProtocolSettings(repetitions=settings.repetitions)
    done = {(t.participant, t.condition, t.speed) for t in store.completed_trials()}
    answered = set(store.questionnaires()["participant"])
    total = len(cohort) * len(protocol.conditions) * len(protocol.speeds)
    simulated = skipped = 0
    with progress.bar("simulating the participants' trials", total) as advance:
        for index, participant in enumerate(cohort):
            pid = participant.participant_id
            trials: list[TrialSimulation] = []
            for condition in condition_order(settings.seed, index, protocol.conditions):
                for speed in protocol.speeds:
                    stored = (pid, condition, speed) in done
                    if stored and pid in answered:
                        skipped += 1
                        advance(simulated + skipped)
                        continue
                    trial = simulate_trial(
                        participant,
                        condition,
                        speed,
                        model=model,
                        settings=protocol,
                        seed=trial_seed(settings.seed, index, condition, speed),
                    )
                    trials.append(trial)
                    if stored:
                        skipped += 1
                    else:
                        _store_trial(store, trial, settings)
                        simulated += 1
                    advance(simulated + skipped)
            if pid not in answered:
                answers = questionnaire_answers(trials, seed=settings.seed)
                store.write_questionnaires(answers.rename(columns={"participant_id": "participant"}))
    return simulated, skipped


def _store_trial(store: StudyStore, trial: TrialSimulation, settings: StudySettings) -> None:
    support = c.CONDITION_SUPPORT[trial.condition]
    frame = trial.to_pandas().loc[:, list(c.TRIAL_COLUMNS)]
    info = TrialInfo(
        participant=trial.participant.participant_id,
        condition=trial.condition,
        speed=trial.speed,
        support=support if isinstance(support, float) else None,
        metadata={
            "backend": "simulation",
            "bowden_version": __version__,
            "seed": trial.seed,
            "repetitions": trial.repetitions,
            "movement_start_s": trial.movement_start_s,
        },
    )
    store.write_trial(info, frame, emg=trial.emg() if settings.store_emg else None)
