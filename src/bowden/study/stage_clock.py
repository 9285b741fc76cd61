"""Wall and CPU seconds per stage of ``bowden study``, the CPU of its worker processes included.

CPU over wall is how many cores a stage kept busy (2.0: both of a 2-core machine). On a shared
machine the wall clock also counts time other processes held the cores; the CPU time does not.
The workers' CPU is read from the process tree (psutil, when installed); without it only this
process and its finished children count. Workers of a Dask cluster are not counted.
"""

from __future__ import annotations

import importlib
import os
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any


def _children_cpu(process: Any) -> float:
    total = 0.0
    for child in process.children(recursive=True):
        try:
            times = child.cpu_times()
        except Exception:  # the child ended between the listing and the reading
            continue
        total += times.user + times.system
    return total


def process_tree_cpu() -> float:
    """CPU seconds of this process and its live (or finished and waited-for) child processes."""
    own = os.times()
    total = own.user + own.system + own.children_user + own.children_system
    try:
        psutil = importlib.import_module("psutil")  # not a dependency: installed with Dask
    except ImportError:
        return total
    return total + _children_cpu(psutil.Process())


class StageClock:
    """Accumulates ``wall`` and ``cpu`` seconds per stage name."""

    def __init__(self) -> None:
        self.wall: dict[str, float] = {}
        self.cpu: dict[str, float] = {}

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        start, start_cpu = time.perf_counter(), process_tree_cpu()
        try:
            yield
        finally:
            self.wall[name] = self.wall.get(name, 0.0) + time.perf_counter() - start
            self.cpu[name] = self.cpu.get(name, 0.0) + process_tree_cpu() - start_cpu
