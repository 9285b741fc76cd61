"""Connecting to Dask: a local cluster by default, or an existing scheduler by address.

Dask (``distributed``) is the ``cluster`` extra; without it :func:`dask_client` raises a one-line
:class:`~bowden.errors.MissingExtraError` naming the extra. A local cluster runs one single-threaded
worker process per core (the simulation is a compiled loop that holds the GIL's worth of one core, so
processes, not threads, are what scale). Before work is submitted every worker is asked for the digest
of its simulator's source: a remote cluster running another bowden would give other numbers, so it
is refused rather than mixed in.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from bowden.errors import ClusterError, MissingExtraError, ParameterError
from bowden.sim.digest import simulator_digest

INSTALL_HINT = "pip install 'bowden[cluster]'"
_CONNECT_TIMEOUT_S = 10.0
_WORKER_WAIT_S = 30.0


def require_dask(purpose: str) -> Any:
    """The ``distributed`` module, or the one-line :class:`~bowden.errors.MissingExtraError` naming the
    extra (``purpose`` says what needs it). A command calls it before its own imports, which take
    seconds, so that the refusal comes at once."""
    try:
        import distributed
    except ImportError:
        raise MissingExtraError(
            f"{purpose} runs on Dask, which is not installed: {INSTALL_HINT} (the 'cluster' extra)"
        ) from None
    return distributed


@contextmanager
def dask_client(
    scheduler: str | None = None,
    workers: int | None = None,
    *,
    connect_timeout_s: float = _CONNECT_TIMEOUT_S,
    purpose: str = "bowden sweep",
) -> Iterator[Any]:
    """A ``distributed.Client``: on a new local cluster, or on the scheduler at ``scheduler``.

    Parameters
    ----------
    scheduler
        Address of a running scheduler (``tcp://host:8786``); ``None`` starts a local cluster that is
        closed when the block ends, whatever happens inside it.
    workers
        Worker processes of the local cluster (default: the number of cores). Not allowed with
        ``scheduler`` (that cluster has its own workers).
    connect_timeout_s
        How long to keep trying to reach ``scheduler``.
    purpose
        What runs on Dask, for the message when Dask is not installed.
    """
    distributed = require_dask(purpose)
    if scheduler is not None and workers is not None:
        raise ParameterError(
            "--workers sets the size of the local cluster; it cannot be used with --scheduler"
        )
    if workers is not None and not (isinstance(workers, int) and 1 <= workers <= 1024):
        raise ParameterError(f"workers must be an integer in [1, 1024], got {workers!r}")
    if scheduler is None:
        n_workers = workers if workers is not None else (os.cpu_count() or 1)
        with (
            distributed.LocalCluster(
                n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None
            ) as cluster,
            distributed.Client(cluster) as client,
        ):
            check_workers(client)
            yield client
        return
    try:
        client = distributed.Client(scheduler, timeout=connect_timeout_s)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ClusterError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
    try:
        try:
            client.wait_for_workers(1, timeout=_WORKER_WAIT_S)
        except (OSError, TimeoutError) as exc:
            raise ClusterError(
                f"the Dask scheduler at {scheduler} has no workers (waited {_WORKER_WAIT_S:.0f} s): {exc}"
            ) from None
        check_workers(client)
        yield client
    finally:
        client.close()


def check_workers(client: Any) -> int:
    """Number of workers; raises :class:`ClusterError` if any runs another simulator (or no bowden)."""
    ours = simulator_digest()
    try:
        theirs: dict[str, str] = client.run(simulator_digest)
    except ImportError as exc:
        raise ClusterError(f"the Dask workers cannot import bowden ({exc}); install bowden on them") from None
    others = sorted(address for address, digest in theirs.items() if digest != ours)
    if others:
        raise ClusterError(
            f"Dask worker {others[0]} runs another version of bowden.sim than this client "
            f"({theirs[others[0]]} vs {ours}); install the same bowden on every worker"
        )
    if not theirs:
        raise ClusterError("the Dask cluster has no workers")
    return len(theirs)
