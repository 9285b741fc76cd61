"""``bowden study``: the paper end to end on the simulated suit, stage by stage, resumable.

Stages, each writing into the study directory:

1. **bench** — the mannequin identification protocol on the simulated bench → ``bench.parquet``;
2. **identify** — the robust fit per direction → ``model.json`` (and the identification figure);
3. **cohort** — virtual participants drawn like the paper's → the store's ``participants``;
4. **trials** — each participant: no suit first, the other conditions in a seeded random order, three
   speeds, ten repetitions, the identified model in the controller → ``study.db`` (samples, EMG,
   questionnaires). A trial already in the store is skipped, so an interrupted run resumes;
5. **analysis**, **statistics** and **report** — as ``bowden analyze`` does for a real study.

``--force`` starts again from an empty directory's worth of results. A directory whose results the
run cannot vouch for is refused before anything is written: results without ``settings.json`` or of
other settings, and — even with ``--force`` — a store holding trials the pipeline did not record (a
recording from the suit is data, never to be deleted or mixed with a virtual cohort).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

from bowden import contracts as c
from bowden._atomic_file import write_text_atomically
from bowden.engine.pool import Engine, check_workers, study_engine
from bowden.errors import OutputFileError, ParameterError, StoreError
from bowden.identify import TransmissionIdentifier
from bowden.model import CompensationModel
from bowden.model.model_file import load_model, save_model
from bowden.protocol.bench import QUICK_BENCH
from bowden.sim.batch import ProtocolSettings
from bowden.sim.bench import BenchProtocol, run_bench
from bowden.sim.parameters import SuitParameters, check_seed
from bowden.sim.participants import MUSCLE_MODELS, VirtualParticipant, generate_cohort
from bowden.store.ownership import files_not_written_by_study, note_written, read_trial_origins
from bowden.store.study_store import StudyStore
from bowden.study.analyze import AnalysisReport, analyze_store
from bowden.study.compensation.comparison import ComparisonSettings
from bowden.study.compensation.report import compensation_section
from bowden.study.progress import StageProgress
from bowden.study.report.html import HtmlDocument
from bowden.study.stage_clock import StageClock
from bowden.study.trial_runner import TrialRecord, run_trials, study_tasks, warm_up


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
    compensation
        ``"paper"`` (the paper's method, the default: the study reproduces the paper) or ``"dynamic"``
        (the dynamic compensation identified from the same bench, :mod:`bowden.model.dynamic`).
    muscles
        Where the participants' muscle activations come from: ``"simple"`` (the hand-made model, the
        default) or ``"musculoskeletal"`` (MyoArm and static optimisation; needs the ``msk`` extra).
    """

    participants: int = 17
    seed: int = 0
    repetitions: int = c.REPETITIONS_PER_TRIAL
    quick_bench: bool = False
    store_emg: bool = True
    compensation: Literal["paper", "dynamic"] = "paper"
    muscles: Literal["simple", "musculoskeletal"] = "simple"

    def __post_init__(self) -> None:
        if self.muscles not in MUSCLE_MODELS:
            raise ParameterError(f"--muscles must be one of {', '.join(MUSCLE_MODELS)}, got {self.muscles!r}")
        if self.compensation not in ("paper", "dynamic"):
            raise ParameterError(f"compensation must be 'paper' or 'dynamic', got {self.compensation!r}")
        if not 2 <= self.participants <= 200:
            raise ParameterError(f"participants must be between 2 and 200, got {self.participants}")
        if not 1 <= self.repetitions <= 50:
            raise ParameterError(f"repetitions must be between 1 and 50, got {self.repetitions}")
        check_seed(self.seed)


@dataclass
class StudyResult:
    """Where everything went, and how long each stage took (s of wall clock and of CPU).

    ``stage_cpu_seconds`` counts this process and its worker processes (not a Dask cluster's), so
    CPU over wall is how many cores a stage kept busy.
    """

    directory: Path
    report: Path
    store: Path
    model: Path
    trials_simulated: int
    trials_skipped: int
    stage_seconds: dict[str, float] = field(default_factory=dict)
    analysis: AnalysisReport | None = None
    stage_cpu_seconds: dict[str, float] = field(default_factory=dict)
    workers: int = 1


def run_study(
    settings: StudySettings,
    directory: str | Path,
    *,
    force: bool = False,
    progress: StageProgress | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
) -> StudyResult:
    """Run (or resume) the simulated study in ``directory`` and write its report.

    The trials and their analysis run on ``workers`` local processes (None: one per core; 1: this
    process alone) or on the Dask cluster at ``scheduler`` (``tcp://host:8786``); the results are the
    same whichever (:mod:`bowden.engine.pool`). This process stays the store's only writer.

    Raises
    ------
    OutputFileError
        ``directory`` is a file or cannot be created or written.
    StoreError
        Its ``study.db`` holds trials the pipeline did not record, or is not a study store; it holds
        results but no ``settings.json``; its ``settings.json`` is damaged (without ``force``).
    ParameterError
        It holds a run with other settings (without ``force``); ``workers`` out of range or given
        with ``scheduler``.
    MissingExtraError
        ``scheduler`` given without Dask installed (the ``cluster`` extra).
    ClusterError
        The scheduler cannot be reached, has no workers or runs another bowden.
    """
    check_workers(workers)
    if scheduler is not None and workers is not None:
        raise ParameterError("--workers sets the size of the local pool; it cannot be used with --scheduler")
    out = _study_directory(directory)
    progress = progress if progress is not None else StageProgress(enabled=False)
    _check_directory_is_ours(out, settings, force=force)
    with study_engine(workers, scheduler) as engine:
        # The workers load the simulator (and its compiled kernels) while the bench runs here.
        engine.warm_up(warm_up)
        return _run_stages(settings, out, engine, force=force, progress=progress)


def _run_stages(
    settings: StudySettings, out: Path, engine: Engine, *, force: bool, progress: StageProgress
) -> StudyResult:
    clock = StageClock()
    settings_file = out / "settings.json"
    if force:
        for name in _RESULT_FILES:  # the files among them are the pipeline's (checked before)
            (out / name).unlink(missing_ok=True)
    try:
        write_text_atomically(settings_file, json.dumps(asdict(settings), indent=2) + "\n")
    except OSError as error:
        raise OutputFileError(f"cannot write {settings_file}: {error.strerror or error}") from None
    note_written(out, _OWN_FILES)  # what is there was checked to be ours (a directory of an older run too)

    with clock.stage("bench"):
        bench_path = _bench_stage(settings, out, progress)
        note_written(out, [bench_path.name])
    with clock.stage("identify"):
        model_path = out / "model.json"
        if not model_path.exists():
            with progress.spinner("identifying the transmission"):
                identifier = TransmissionIdentifier().fit(bench_path)
            save_model(identifier.model_, model_path)
            note_written(out, [model_path.name])
        model = load_model(model_path)

    store_path = out / "study.db"
    with StudyStore(store_path) as store:
        store.discard_unfinished_trials()
        store.put_artifact("model.json", model_path.read_text())
        store.put_artifact("settings.json", settings_file.read_text())
        with clock.stage("cohort"):
            # The paper's 12 women in 17, kept in proportion for other cohort sizes.
            cohort = generate_cohort(
                settings.seed, n_participants=settings.participants, muscles=settings.muscles
            )
            for participant in cohort:
                store.add_participant(
                    participant.participant_id, participant.subject, {"age_years": participant.age_years}
                )
        with clock.stage("trials"):
            simulated, skipped = _trials_stage(settings, cohort, model, store, progress, engine)

    appendix = None
    if settings.compensation == "dynamic":
        comparison = ComparisonSettings(
            participants=min(3, settings.participants),
            cohort_seed=settings.seed,
            cohort_size=settings.participants,
            repetitions=settings.repetitions,
        )

        def appendix(document: HtmlDocument) -> object:
            with progress.spinner("comparing with the paper's compensation"):
                return compensation_section(document, model, SuitParameters(), comparison)

    with clock.stage("analysis, statistics and report"):
        analysis = analyze_store(
            store_path,
            out / "report.html",
            simulated=True,
            bench_path=bench_path,
            progress=progress,
            timings=clock.wall,
            engine=engine,
            appendix=appendix,
        )
        note_written(out, ["report.html"])
    return StudyResult(
        directory=out,
        report=out / "report.html",
        store=store_path,
        model=model_path,
        trials_simulated=simulated,
        trials_skipped=skipped,
        stage_seconds=clock.wall,
        analysis=analysis,
        stage_cpu_seconds=clock.cpu,
        workers=engine.workers,
    )


# What a run leaves in its directory besides settings.json (--force deletes these).
_RESULT_FILES = ("bench.parquet", "model.json", "study.db", "study.db-wal", "study.db-shm", "report.html")
# Those it writes whole, listed with their hashes (bowden.store.ownership); the store's trials say
# whose it is.
_OWN_FILES = ("bench.parquet", "model.json", "report.html")


def _study_directory(directory: str | Path) -> Path:
    out = Path(directory)
    if out.exists() and not out.is_dir():
        raise OutputFileError(f"--out {out} is a file, not a directory: give a directory for the study")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise OutputFileError(f"cannot create the study directory {out}: {error.strerror or error}") from None
    return out


def _check_directory_is_ours(out: Path, settings: StudySettings, *, force: bool) -> None:
    """Refuse a directory whose results this run cannot vouch for, before anything is written.

    A store holding trials the pipeline did not record is refused even with ``force``: those are
    recordings, and ``force`` would delete them. Results without a settings.json cannot be checked
    against ``settings``; results of other settings would mix two studies.
    """
    store = out / "study.db"
    origins = read_trial_origins(store)
    if origins.foreign:
        shown = "; ".join(origins.foreign[:3]) + ("; ..." if len(origins.foreign) > 3 else "")
        raise StoreError(
            f"{store} holds {len(origins.foreign)} trial(s) that bowden study did not record ({shown}): "
            "bowden study never deletes or adds to another recording's store; use another --out directory"
        )
    if force:
        _refuse_files_not_ours(out)
        return
    settings_file = out / "settings.json"
    stored = _read_settings(settings_file)
    if stored is None:
        results = [name for name in ("bench.parquet", "model.json") if (out / name).exists()]
        if origins.n_trials:
            results.insert(0, f"study.db with {origins.n_trials} trial(s)")
        if results:
            raise StoreError(
                f"{out} holds {', '.join(results)} but no settings.json, so they cannot be checked against "
                "these settings: use another --out directory, or --force to start again"
            )
    # Runs from before an option existed used its default.
    elif {"compensation": "paper", "muscles": "simple", **stored} != asdict(settings):
        raise ParameterError(
            f"{out} holds a study run with other settings ({settings_file}); "
            "use another --out directory or --force to start again"
        )
    _refuse_files_not_ours(out)


def _refuse_files_not_ours(out: Path) -> None:
    """Refuse a directory holding a file the pipeline would replace or resume from but did not
    write as it is (a lab's own model.json): never replaced, even with ``--force``."""
    foreign = files_not_written_by_study(out, _OWN_FILES)
    if foreign:
        raise StoreError(
            f"{out} holds {', '.join(foreign)}: bowden study replaces or reuses only the files it wrote, "
            "even with --force; move them out of the directory or use another --out directory"
        )


def _read_settings(path: Path) -> dict[str, Any] | None:
    """The settings a previous run stored, None if there is no such file."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as error:
        raise StoreError(f"cannot read {path}: {error}; use --force to start again") from None
    try:
        stored = json.loads(text)
    except json.JSONDecodeError as error:
        raise StoreError(
            f"{path} is damaged (not JSON: line {error.lineno}, column {error.colno}: {error.msg}); "
            "use --force to start again or another --out directory"
        ) from None
    if not isinstance(stored, dict):
        raise StoreError(
            f"{path} is damaged (a JSON {type(stored).__name__}, not the settings object); "
            "use --force to start again or another --out directory"
        )
    return stored


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
    engine: Engine,
) -> tuple[int, int]:
    protocol = ProtocolSettings(repetitions=settings.repetitions, compensation=settings.compensation)
    done = {(t.participant, t.condition, t.speed) for t in store.completed_trials()}
    answered = set(store.questionnaires()["participant"])
    tasks = list(
        study_tasks(
            cohort, model=model, protocol=protocol, seed=settings.seed, store_emg=settings.store_emg,
            done=done, answered=answered,
        )
    )
    # A participant's questionnaires are answered from all of their trials, after the last one.
    expected: dict[str, int] = {}
    for task in tasks:
        pid = task.participant.participant_id
        if pid not in answered:
            expected[pid] = expected.get(pid, 0) + 1
    total = len(cohort) * len(protocol.conditions) * len(protocol.speeds)
    with progress.bar("simulating the participants' trials", total) as advance:
        count = total - len(tasks)  # trials in the store whose participant has answered: not re-run
        advance(count)

        def on_trial(_record: TrialRecord, _trial_id: int | None) -> None:
            nonlocal count
            count += 1
            advance(count)

        simulated = run_trials(
            engine, iter(tasks), store, seed=settings.seed, expected=expected, on_trial=on_trial
        )
    return simulated, total - simulated
