"""Where the study's tasks run: in this process, on worker processes, or on a Dask cluster.

One engine serves every stage of ``bowden study`` (the trials, their analysis, the statistics'
fits), so its workers start once and stay warm (imports done, compiled kernels loaded). Every map
gives its results in the order of its tasks, whatever order the workers finish in: what a study
writes and computes never depends on the number of workers.

Worker processes are started by ``spawn``, not ``fork``: the caller may hold threads (progress
bars, a server) whose locks a forked child would inherit mid-use. A local pool's workers can open
the study's files by path (:attr:`Engine.shares_files`); a Dask cluster's may be other machines,
so its tasks get their data sent with them.
"""

from __future__ import annotations

import multiprocessing
import os
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from contextlib import contextmanager
from typing import Any, Protocol, TypeVar

from bowden.errors import ParameterError

T = TypeVar("T")
R = TypeVar("R")
R_co = TypeVar("R_co", covariant=True)

MAX_WORKERS = 1024
# A spawned worker first imports the analysis and loads its compiled kernels, about 5 s of a core
# (measured on 2 cores: a store of 4 short trials took 17 s on a pool of two, 6 s in one process);
# a study trial's analysis takes about a second. So a worker is worth starting for about ten trials.
TASKS_PER_WORKER = 10


class Pending(Protocol[R_co]):
    """A result on its way (``concurrent.futures.Future`` and Dask's futures both are)."""

    def result(self) -> R_co: ...


class Engine:
    """Runs tasks in this process; the base of the pooled engines.

    Attributes
    ----------
    workers
        Tasks that run at the same time.
    shares_files
        Whether the workers can open this machine's files by path.
    """

    workers: int = 1
    shares_files: bool = True

    def map(
        self, function: Callable[[T], R], items: Iterable[T], *, window: int | None = None
    ) -> Iterator[R]:
        """``function`` over ``items``, results in input order, at most ``window`` tasks in flight."""
        return map(function, items)

    def submit(self, function: Callable[..., R], *args: Any) -> Pending[R]:
        """Start ``function(*args)`` and return what gives its result."""
        future: Future[R] = Future()
        try:
            future.set_result(function(*args))
        except Exception as error:  # delivered by result(), as a pool's future does
            future.set_exception(error)
        return future

    def warm_up(self, function: Callable[[], object]) -> None:
        """Run ``function`` once in each worker ahead of the work (imports, compiled kernels)."""

    def close(self) -> None:
        """Stop the workers (nothing to stop here)."""


def _bounded_ordered(
    submit: Callable[[T], Pending[R]], items: Iterable[T], window: int
) -> Iterator[R]:
    """Submit ahead of what is consumed, at most ``window`` tasks in flight, yield in input order."""
    pending: deque[Pending[R]] = deque()
    for item in items:
        pending.append(submit(item))
        if len(pending) >= window:
            yield pending.popleft().result()
    while pending:
        yield pending.popleft().result()


class ProcessEngine(Engine):
    """A pool of ``workers`` spawned processes on this machine."""

    shares_files = True

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self._pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))

    def map(
        self, function: Callable[[T], R], items: Iterable[T], *, window: int | None = None
    ) -> Iterator[R]:
        # Two tasks per worker keep each busy while the parent takes the previous result.
        depth = window if window is not None else 2 * self.workers
        return _bounded_ordered(lambda item: self._pool.submit(function, item), items, depth)

    def submit(self, function: Callable[..., R], *args: Any) -> Pending[R]:
        return self._pool.submit(function, *args)

    def warm_up(self, function: Callable[[], object]) -> None:
        # One task per worker: the pool starts a process for each task no idle process can take.
        for _ in range(self.workers):
            self._pool.submit(function)

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


class DaskEngine(Engine):
    """The workers of a Dask cluster (``bowden[cluster]``), through a connected client."""

    shares_files = False

    def __init__(self, client: Any, workers: int) -> None:
        self.workers = workers
        self._client = client

    def map(
        self, function: Callable[[T], R], items: Iterable[T], *, window: int | None = None
    ) -> Iterator[R]:
        depth = window if window is not None else 2 * self.workers
        return _bounded_ordered(lambda item: self.submit(function, item), items, depth)

    def submit(self, function: Callable[..., R], *args: Any) -> Pending[R]:
        # pure=False: two tasks with equal arguments are still two tasks (no hashing of large data).
        future: Pending[R] = self._client.submit(function, *args, pure=False)
        return future

    def warm_up(self, function: Callable[[], object]) -> None:
        # Dask's workers outlive a study: they are warm after the first.
        return None


def check_workers(workers: object) -> int | None:
    """``workers`` as given on the command line or to :func:`run_study`: None or 1…1024."""
    if workers is None:
        return None
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= MAX_WORKERS:
        raise ParameterError(f"workers must be an integer in [1, {MAX_WORKERS}], got {workers!r}")
    return workers


def pool_size(tasks: int, workers: int | None = None) -> int:
    """``workers`` if given, else one per core but no more than one per :data:`TASKS_PER_WORKER`
    tasks (at least one: 1 runs in this process, with no pool to start)."""
    checked = check_workers(workers)
    if checked is not None:
        return checked
    return max(1, min(os.cpu_count() or 1, tasks // TASKS_PER_WORKER))


@contextmanager
def study_engine(workers: int | None = None, scheduler: str | None = None) -> Iterator[Engine]:
    """The engine of a study: Dask at ``scheduler``, else ``workers`` local processes (None: one per core).

    ``workers=1`` runs everything in this process. The workers are stopped when the block ends.

    Raises
    ------
    ParameterError
        Both ``workers`` and ``scheduler`` given, or ``workers`` out of range.
    MissingExtraError
        ``scheduler`` given and Dask (the ``cluster`` extra) is not installed.
    ClusterError
        The scheduler cannot be reached, has no workers, or its workers run another bowden.
    """
    workers = check_workers(workers)
    if scheduler is not None:
        if workers is not None:
            raise ParameterError(
                "--workers sets the size of the local pool; it cannot be used with --scheduler"
            )
        from bowden.engine.cluster import check_workers as check_cluster
        from bowden.engine.cluster import dask_client

        with dask_client(scheduler, purpose="bowden study --scheduler") as client:
            yield DaskEngine(client, check_cluster(client))
        return
    count = workers if workers is not None else (os.cpu_count() or 1)
    if count == 1:
        yield Engine()
        return
    engine = ProcessEngine(count)
    try:
        yield engine
    finally:
        engine.close()
