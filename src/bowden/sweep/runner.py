"""Run a sweep on a Dask client: identify each suit once, score every (point, participant), keep it all.

The task graph: one :func:`~bowden.sweep.task.identify_suit` per distinct identification (suit and
seed; a single one with ``identification = "nominal"``), and one
:func:`~bowden.sweep.task.score_participant` per point and participant, depending on its suit's
model. Dask ships the model from the worker that identified it to the workers that need it. The
client writes each task's rows to its own Parquet part the moment it finishes
(:class:`~bowden.sweep.output.SweepDirectory`), so:

* a worker that dies loses only the task it was running, which the scheduler runs again elsewhere
  (``distributed.scheduler.allowed-failures``, 3 by default; a task that kills every worker it
  touches ends the run with :class:`~bowden.errors.ClusterError`);
* a run that stops for any reason keeps every finished task; the next run of the same spec in the
  same directory submits only what is missing, reusing identified models.

Seeds: every trial is seeded by :func:`bowden.sim.trial_seed` from the point's seed, the
participant's index, the condition and the speed, exactly as ``bowden study`` does, so a point's rows
do not depend on which worker ran them, and every point of a seed sees the same participants and the
same noise (paired comparisons between points).
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from bowden.errors import BowdenError, ClusterError
from bowden.model import CompensationModel
from bowden.sim.batch import ProtocolSettings
from bowden.sim.parameters import SuitParameters
from bowden.sim.participants import VirtualParticipant, generate_cohort
from bowden.study.progress import StageProgress
from bowden.sweep.output import SweepDirectory
from bowden.sweep.spec import SweepPoint, SweepSpec
from bowden.sweep.summary import summarize_points
from bowden.sweep.task import identify_suit, score_participant


@dataclass
class SweepRun:
    """What a run did and where it went."""

    directory: Path
    results_path: Path
    points_path: Path
    results: pd.DataFrame
    points: pd.DataFrame
    tasks_computed: int
    tasks_skipped: int
    models_identified: int
    workers: int
    seconds: float
    skipped_combinations: int = 0
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class _Task:
    point: SweepPoint
    suit: SuitParameters
    suit_id: str
    participant: VirtualParticipant
    index: int


def cohort(spec: SweepSpec, seed: int) -> tuple[VirtualParticipant, ...]:
    """The virtual participants of ``seed`` (drawn like ``bowden study``'s cohort)."""
    return generate_cohort(seed, n_participants=spec.participants)


def protocol_settings(spec: SweepSpec) -> ProtocolSettings:
    """The protocol every point runs."""
    return ProtocolSettings(conditions=spec.conditions, speeds=spec.speeds, repetitions=spec.repetitions)


def identification_suit(spec: SweepSpec, point: SweepPoint, base: SuitParameters) -> SuitParameters:
    """The suit whose bench gives the point's model: its own, or the default one (``nominal``)."""
    return point.suit(base) if spec.identification == "per-suit" else base


def suit_id(suit: SuitParameters, bench: str, seed: int) -> str:
    """Digest of one identification: the bench's suit, protocol and noise seed."""
    payload = json.dumps({"suit": asdict(suit), "bench": bench, "seed": seed}, sort_keys=True, default=str)
    return hashlib.sha256(payload.encode()).hexdigest()[:16]


def run_sweep(
    spec: SweepSpec,
    out: str | Path,
    client: Any,
    *,
    force: bool = False,
    progress: StageProgress | None = None,
) -> SweepRun:
    """Run (or resume) ``spec`` on ``client`` (a ``distributed.Client``), writing into ``out``."""
    start = time.perf_counter()
    progress = progress if progress is not None else StageProgress(enabled=False)
    directory = SweepDirectory(out)
    directory.prepare(spec, force=force)
    tasks, bench_suits = _tasks(spec)
    pending = [t for t in tasks if not directory.has_part(t.point.point_id, t.participant.participant_id)]
    workers = len(client.nthreads())
    models, identify_futures = _models(client, spec, directory, bench_suits, pending)
    protocol = protocol_settings(spec)
    score_futures: dict[Any, _Task] = {}
    for t in pending:
        future = client.submit(
            score_participant, t.point, t.suit, models[t.suit_id], t.participant, t.index, protocol,
            key=f"score-{t.point.point_id}-{t.participant.participant_id}",
        )
        score_futures[future] = t

    skipped = len(tasks) - len(pending)
    description = f"sweep {spec.name}: {len(spec.points())} points × {spec.participants} participants"
    with progress.bar(description, len(tasks)) as advance:
        advance(skipped)
        done = _collect(client, directory, identify_futures, score_futures, skipped, advance)

    keys = [(t.point.point_id, t.participant.participant_id) for t in tasks]
    results = directory.read_parts(keys)
    results_path = directory.write_results(results)
    points = summarize_points(results, spec)
    points_path = directory.write_points(points)
    notes = []
    if spec.skipped_combinations:
        notes.append(
            f"{spec.skipped_combinations} combination(s) of the axes left out: their blend had "
            "blend_velocity_01_rad_s >= blend_velocity_99_rad_s"
        )
    return SweepRun(
        directory=directory.path,
        results_path=results_path,
        points_path=points_path,
        results=results,
        points=points,
        tasks_computed=done,
        tasks_skipped=skipped,
        models_identified=len(identify_futures),
        workers=workers,
        seconds=time.perf_counter() - start,
        skipped_combinations=spec.skipped_combinations,
        notes=notes,
    )


def _tasks(spec: SweepSpec) -> tuple[list[_Task], dict[str, tuple[SuitParameters, int]]]:
    """One task per point and participant, and the bench suit (with its seed) each suit id is
    identified on."""
    base = SuitParameters()
    cohorts = {seed: cohort(spec, seed) for seed in spec.seeds}
    tasks: list[_Task] = []
    bench_suits: dict[str, tuple[SuitParameters, int]] = {}
    for point in spec.points():
        bench_suit = identification_suit(spec, point, base)
        sid = suit_id(bench_suit, spec.bench, point.seed)
        bench_suits[sid] = (bench_suit, point.seed)
        suit = point.suit(base)
        for index, participant in enumerate(cohorts[point.seed]):
            tasks.append(_Task(point, suit, sid, participant, index))
    return tasks, bench_suits


def _models(client: Any, spec: SweepSpec, directory: SweepDirectory,
            bench_suits: dict[str, tuple[SuitParameters, int]],
            pending: list[_Task]) -> tuple[dict[str, Any], dict[Any, str]]:
    """Each pending suit's model: the stored one, else a future identifying it (also returned, keyed
    to its suit id, so that its result is stored when it comes)."""
    models: dict[str, Any] = {}
    identify_futures: dict[Any, str] = {}
    for sid in sorted({t.suit_id for t in pending}):
        stored = directory.load_model(sid)
        if stored is not None:
            models[sid] = stored
        else:
            bench_suit, seed = bench_suits[sid]
            future = client.submit(identify_suit, bench_suit, spec.bench, seed, key=f"identify-{sid}")
            identify_futures[future] = sid
            models[sid] = future
    return models, identify_futures


def _collect(
    client: Any,
    directory: SweepDirectory,
    identify_futures: dict[Any, str],
    score_futures: dict[Any, _Task],
    skipped: int,
    advance: Any,
) -> int:
    """Write each finished task's output as it arrives; return the number of tasks computed."""
    from distributed import as_completed  # the cluster extra is present: we hold a client

    done = 0
    all_futures = [*identify_futures, *score_futures]
    try:
        for future in as_completed(all_futures):  # type: ignore[no-untyped-call]
            if future in identify_futures:
                model: CompensationModel = _result(future, f"identifying suit {identify_futures[future]}")
                directory.save_model(identify_futures[future], model)
                continue
            task = score_futures[future]
            label = f"point {task.point.label()}, participant {task.participant.participant_id}"
            frame: pd.DataFrame = _result(future, label)
            directory.write_part(task.point.point_id, task.participant.participant_id, frame)
            future.release()
            done += 1
            advance(skipped + done)
    finally:
        unfinished = [f for f in all_futures if not f.done()]
        if unfinished:
            client.cancel(unfinished)
    return done


def _result(future: Any, label: str) -> Any:
    """The task's result; errors of the cluster become :class:`ClusterError` naming the task."""
    from distributed import KilledWorker

    try:
        return future.result()
    except BowdenError:
        raise
    except KilledWorker as exc:
        raise ClusterError(
            f"{label}: its worker died each time it ran it ({exc}); the finished tasks are kept, "
            "re-run the same command to resume"
        ) from None
    except (OSError, TimeoutError) as exc:
        raise ClusterError(
            f"{label}: lost contact with the Dask cluster ({exc}); the finished tasks are kept, "
            "re-run the same command to resume"
        ) from None
