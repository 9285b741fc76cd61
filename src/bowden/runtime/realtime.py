"""Real-time settings for the control loop's thread, applied where the OS allows and said where not.

Inside :func:`realtime` the calling thread (the loop's) may get:

* ``SCHED_FIFO`` at ``priority``: it preempts every normal process as soon as its sleep ends, so a
  busy machine no longer delays the cycles. The loop sleeps between cycles, so it cannot starve the
  machine; the kernel's RT throttling (95 % by default) is the backstop. Needs root or
  ``CAP_SYS_NICE`` (or an ``rtprio`` limit): see docs/hardware.md, "Real-time settings";
* a CPU affinity (an isolated core, say);
* a short interpreter switch interval (0.5 ms instead of Python's 5 ms), so that when the loop's
  sleep ends while another thread of the process holds the interpreter lock (the recorder, the load
  cell's reader), the loop gets it back within half a millisecond;
* no garbage collection: what exists is moved to the permanent generation (``gc.freeze``) and
  automatic collection is off for the run, so a collection pause never lands in a cycle. The loop
  allocates no reference cycles; collection resumes (and runs once) when the block ends.

Everything is restored on the way out, also when the block raises. A setting the OS refuses is
reported in :attr:`RealtimeReport.unavailable` and never raises.
"""

from __future__ import annotations

import gc
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from bowden.errors import ParameterError


@dataclass(frozen=True, kw_only=True)
class RealtimeConfig:
    """What to ask of the OS for the loop's thread.

    Parameters
    ----------
    priority
        ``SCHED_FIFO`` priority (1–99), or None to leave the scheduling policy alone.
    cpus
        CPUs the loop's thread may run on, or None to leave its affinity alone.
    freeze_gc
        Freeze the heap and turn automatic garbage collection off for the run.
    switch_interval_s
        The interpreter's thread switch interval during the run (None: leave it).
    """

    priority: int | None = 50
    cpus: frozenset[int] | None = None
    freeze_gc: bool = True
    switch_interval_s: float | None = 0.0005

    def __post_init__(self) -> None:
        priority = self.priority
        if priority is not None and (isinstance(priority, bool) or not isinstance(priority, int)
                                     or not 1 <= priority <= 99):
            raise ParameterError(f"RealtimeConfig.priority must be 1–99 or None, got {priority!r}")
        if self.cpus is not None and (not self.cpus or not all(
                isinstance(c, int) and not isinstance(c, bool) and c >= 0 for c in self.cpus)):
            raise ParameterError(f"RealtimeConfig.cpus must be CPU numbers ≥ 0, got {self.cpus!r}")
        interval = self.switch_interval_s
        if interval is not None and not (isinstance(interval, float | int) and 1e-5 <= interval <= 0.1):
            raise ParameterError(
                f"RealtimeConfig.switch_interval_s must be in [1e-5, 0.1] s, got {interval!r}"
            )


@dataclass(frozen=True)
class RealtimeReport:
    """What was applied, and what the OS refused (with why)."""

    applied: tuple[str, ...]
    unavailable: tuple[str, ...]

    def describe(self) -> str:
        """One line for the run summary."""
        parts = list(self.applied) or ["none"]
        if self.unavailable:
            parts.append("unavailable: " + "; ".join(self.unavailable))
        return ", ".join(parts)


def _refusal(error: OSError) -> str:
    return error.strerror or str(error)


@contextmanager
def realtime(config: RealtimeConfig) -> Iterator[RealtimeReport]:
    """Apply ``config`` to the calling thread for the duration of the block (see the module)."""
    applied: list[str] = []
    unavailable: list[str] = []
    restore_policy: tuple[int, int] | None = None
    restore_cpus: set[int] | None = None
    gc_was_enabled = gc.isenabled()

    if config.priority is not None:
        if not hasattr(os, "sched_setscheduler"):
            unavailable.append("SCHED_FIFO: not offered by this OS")
        else:
            try:
                previous = (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(config.priority))
            except OSError as error:
                unavailable.append(f"SCHED_FIFO: {_refusal(error)} (needs root or CAP_SYS_NICE; "
                                   "see docs/hardware.md)")
            else:
                restore_policy = previous
                applied.append(f"SCHED_FIFO {config.priority}")
    if config.cpus is not None:
        if not hasattr(os, "sched_setaffinity"):
            unavailable.append("CPU affinity: not offered by this OS")
        else:
            try:
                previous_cpus = os.sched_getaffinity(0)
                os.sched_setaffinity(0, config.cpus)
            except OSError as error:
                unavailable.append(f"CPU affinity {sorted(config.cpus)}: {_refusal(error)}")
            else:
                restore_cpus = previous_cpus
                applied.append(f"CPU {', '.join(str(c) for c in sorted(config.cpus))}")
    previous_interval = sys.getswitchinterval()
    if config.switch_interval_s is not None:
        sys.setswitchinterval(config.switch_interval_s)
        applied.append(f"switch interval {1e3 * config.switch_interval_s:g} ms")
    if config.freeze_gc:
        gc.collect()
        gc.freeze()
        gc.disable()
        applied.append("gc frozen, no collection in the loop")
    try:
        yield RealtimeReport(tuple(applied), tuple(unavailable))
    finally:
        sys.setswitchinterval(previous_interval)
        if config.freeze_gc:
            gc.unfreeze()
            if gc_was_enabled:
                gc.enable()
        if restore_cpus is not None:
            os.sched_setaffinity(0, restore_cpus)
        if restore_policy is not None:
            policy, priority = restore_policy
            os.sched_setscheduler(0, policy, os.sched_param(priority))
