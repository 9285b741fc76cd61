"""Where tasks run: in this process, on local worker processes, or on a Dask cluster.

Below both :mod:`bowden.study` and :mod:`bowden.sweep`, which run their tasks here; it imports
neither (``tests/test_architecture.py``).
"""

from bowden.engine.cluster import dask_client
from bowden.engine.pool import Engine, Pending, check_workers, study_engine

__all__ = ["Engine", "Pending", "check_workers", "dask_client", "study_engine"]
