"""The study's trials as tasks: a worker simulates a trial and synthesises its sEMG, the caller stores it.

A :class:`TrialTask` is everything one trial needs (participant, condition, speed, the identified
model, the protocol and the trial's own seed, :func:`bowden.sim.batch.trial_seed`), so any worker —
a local process or a Dask worker elsewhere — computes the same trial. It sends back a
:class:`TrialRecord`: the samples and raw sEMG already encoded as the store keeps them
(:mod:`bowden.store.trial_encoding`: the compression runs on the workers, not in the one writer), and
the few numbers the questionnaires need (:class:`bowden.sim.questionnaires.TrialLoad`), never the
whole simulation.

:func:`run_trials` maps the tasks on an engine and writes the records into the store in task order
from this one process (SQLite has one writer; the order makes the trial ids independent of which
worker finishes first). Writing one trial overlaps the simulation of the next ones. After a
participant's last trial its questionnaire answers are written.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

from bowden import __version__
from bowden import contracts as c
from bowden.engine.pool import Engine
from bowden.model import CompensationModel
from bowden.model.model_record import model_record
from bowden.runtime.recorder import TrialInfo
from bowden.sim.batch import ProtocolSettings, condition_order, session_trial, simulate_trial, trial_seed
from bowden.sim.participants import VirtualParticipant
from bowden.sim.questionnaires import TrialLoad, answers_from_loads, trial_load
from bowden.store.ownership import RECORDED_BY_KEY, STUDY_PIPELINE
from bowden.store.study_store import StudyStore
from bowden.store.trial_encoding import EncodedTrial, encode_trial


@dataclass(frozen=True, kw_only=True)
class TrialTask:
    """One trial to simulate; ``store`` False when it is in the store already (questionnaires only)."""

    participant: VirtualParticipant
    condition: str
    speed: str
    model: CompensationModel
    protocol: ProtocolSettings
    seed: int
    store_emg: bool
    store: bool
    session_trial: int = 0  # trials the participant did before this one (practice)


@dataclass(frozen=True, kw_only=True)
class TrialRecord:
    """A simulated trial as the store takes it (``encoded`` None when it is not to be stored)."""

    info: TrialInfo
    encoded: EncodedTrial | None
    load: TrialLoad


def simulate_task(task: TrialTask) -> TrialRecord:
    """Simulate one trial and synthesise its sEMG (module level, so that workers can run it)."""
    trial = simulate_trial(
        task.participant, task.condition, task.speed, model=task.model, settings=task.protocol,
        seed=task.seed, session_trial=task.session_trial,
    )
    support = c.CONDITION_SUPPORT[task.condition]
    info = TrialInfo(
        participant=task.participant.participant_id,
        condition=task.condition,
        speed=task.speed,
        support=support if isinstance(support, float) else None,
        metadata={
            "backend": c.BACKEND_SIM,
            RECORDED_BY_KEY: STUDY_PIPELINE,
            "bowden_version": __version__,
            "seed": trial.seed,
            "repetitions": trial.repetitions,
            "movement_start_s": trial.movement_start_s,
            # As bowden run records it: the controller's compensation (None without the suit) and the
            # model's SHA-256 (that of the study's model.json, which save_model wrote) and coefficients.
            "compensation": task.protocol.compensation if support is not None else None,
            "model": "model.json",
            **model_record(task.model),
        },
    )
    encoded = None
    if task.store:
        samples = trial.to_pandas().loc[:, list(c.TRIAL_COLUMNS)]
        encoded = encode_trial(samples, trial.emg() if task.store_emg else None)
    return TrialRecord(info=info, encoded=encoded, load=trial_load(trial))


def warm_up() -> None:
    """Load what a trial needs in a fresh worker: the simulator's modules and compiled kernels.

    A one-repetition trial of a default participant, thrown away; the compiled kernels come from
    numba's disk cache (or are compiled once and cached there).
    """
    from bowden.sim.participants import generate_cohort

    participant = generate_cohort(0, n_participants=2)[0]
    model = CompensationModel.from_friction(k=0.1)
    protocol = ProtocolSettings(repetitions=1, lead_in_s=0.1, tail_s=0.0, speeds=(c.SPEEDS[-1],))
    task = TrialTask(
        participant=participant, condition=c.CONDITIONS[-1], speed=c.SPEEDS[-1], model=model,
        protocol=protocol, seed=0, store_emg=True, store=True,
    )
    simulate_task(task)


def study_tasks(
    cohort: tuple[VirtualParticipant, ...],
    *,
    model: CompensationModel,
    protocol: ProtocolSettings,
    seed: int,
    store_emg: bool,
    done: set[tuple[str, str, str]],
    answered: set[str],
) -> Iterator[TrialTask]:
    """The tasks in the protocol's order: no suit first, the other conditions in the seeded order.

    A trial in ``done`` is not simulated again unless its participant's questionnaires are missing
    (they are answered from every trial of the participant).
    """
    for index, participant in enumerate(cohort):
        pid = participant.participant_id
        order = condition_order(seed, index, protocol.conditions)
        for condition in order:
            for speed in protocol.speeds:
                stored = (pid, condition, speed) in done
                if stored and pid in answered:
                    continue
                yield TrialTask(
                    participant=participant, condition=condition, speed=speed, model=model, protocol=protocol,
                    seed=trial_seed(seed, index, condition, speed), store_emg=store_emg, store=not stored,
                    session_trial=session_trial(order, condition, protocol.speeds, speed),
                )


def run_trials(
    engine: Engine,
    tasks: Iterator[TrialTask],
    store: StudyStore,
    *,
    seed: int,
    expected: dict[str, int],
    on_trial: Callable[[TrialRecord, int | None], None] | None = None,
) -> int:
    """Simulate ``tasks`` on ``engine`` and store each record in task order; return the trials written.

    ``expected`` gives, per participant whose questionnaires are missing, how many of the tasks are
    theirs: after the last one their answers are written. ``on_trial(record, trial_id)`` follows each
    record (``trial_id`` None when the trial was in the store already).
    """
    written = 0
    loads: dict[str, list[TrialLoad]] = {}
    for record in engine.map(simulate_task, tasks):
        trial_id = None
        if record.encoded is not None:
            trial_id = store.write_encoded_trial(record.info, record.encoded)
            written += 1
        pid = record.info.participant
        if pid in expected:
            loads.setdefault(pid, []).append(record.load)
            if len(loads[pid]) == expected[pid]:
                answers = answers_from_loads(loads.pop(pid), seed=seed)
                store.write_questionnaires(answers.rename(columns={"participant_id": "participant"}))
        if on_trial is not None:
            on_trial(record, trial_id)
    return written

