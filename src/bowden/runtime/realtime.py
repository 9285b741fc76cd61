"""Real-time settings for the control loop's thread, applied where the OS allows and said where not.

Inside :func:`realtime` the calling thread (the loop's) may get:

* ``SCHED_FIFO`` at ``priority``: it preempts every normal process as soon as its sleep ends, so a
  busy machine no longer delays the cycles. The loop sleeps between cycles, so it cannot starve the
  machine; the kernel's RT throttling (95 % by default) is the backstop. Needs root or
  ``CAP_SYS_NICE`` (or an ``rtprio`` limit): see docs/hardware.md, "Real-time settings".
  The process's other Python threads (the load cell's reader, the recorder's writer) get the same
  priority for the block: they share the interpreter lock with the loop, and a normal thread that
  holds the lock when the scheduler takes its CPU away keeps the loop waiting until it gets a CPU
  back (a priority inversion: on the simulated bench, whose devices run under ``SCHED_FIFO`` on the
  same machine, each CAN send of the loop waited 0.18 ms on average for the lock, 2026-11-28);
* a CPU affinity (an isolated core, say);
* a short interpreter switch interval (0.5 ms instead of Python's 5 ms), so that when the loop's
  sleep ends while another thread of the process holds the interpreter lock (the recorder, the load
  cell's reader), the loop gets it back within half a millisecond;
* no garbage collection: what exists is moved to the permanent generation (``gc.freeze``) and
  automatic collection is off for the run, so a collection pause never lands in a cycle. The loop
  allocates no reference cycles; collection resumes, and runs once, when the block ends;
* the process's memory locked in RAM (``mlockall(MCL_CURRENT | MCL_FUTURE)``, off by default), so
  that no page of it is swapped out or faulted in lazily during a cycle. It is only done where the
  locked-memory limit cannot make a later allocation fail (``CAP_IPC_LOCK`` or an unlimited
  ``memlock`` limit).

Everything is restored on the way out, in reverse order, also when the block raises; the one
collection runs last, back at the thread's normal priority. A setting the OS refuses is reported in
:attr:`RealtimeReport.unavailable` and never raises. The scheduling policy and the affinity are the
calling thread's (Linux: pid 0 is the calling thread); the memory lock and the garbage collector are
the whole process's.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import gc
import os
import platform
import sys
import threading
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path

from bowden.errors import ParameterError

__all__ = ["RealtimeConfig", "RealtimeReport", "at_normal_priority", "realtime"]

_REALTIME_POLICIES = frozenset(getattr(os, name) for name in ("SCHED_FIFO", "SCHED_RR")
                               if hasattr(os, name))

_CAP_IPC_LOCK = 14  # bit of the capability in /proc/<pid>/status CapEff


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
    lock_memory
        Lock the process's current and future memory in RAM for the run (``mlockall``).
    switch_interval_s
        The interpreter's thread switch interval during the run, s (None: leave it).
    """

    priority: int | None = 50
    cpus: frozenset[int] | None = None
    freeze_gc: bool = True
    lock_memory: bool = False
    switch_interval_s: float | None = 0.0005

    def __post_init__(self) -> None:
        priority = self.priority
        if priority is not None and (isinstance(priority, bool) or not isinstance(priority, int)
                                     or not 1 <= priority <= 99):
            raise ParameterError(f"RealtimeConfig.priority must be 1–99 or None, got {priority!r}")
        if self.cpus is not None and (not isinstance(self.cpus, frozenset) or not self.cpus or not all(
                isinstance(c, int) and not isinstance(c, bool) and c >= 0 for c in self.cpus)):
            raise ParameterError(
                f"RealtimeConfig.cpus must be a non-empty frozenset of CPU numbers ≥ 0, got {self.cpus!r}"
            )
        for name in ("freeze_gc", "lock_memory"):
            value = getattr(self, name)
            if not isinstance(value, bool):
                raise ParameterError(f"RealtimeConfig.{name} must be True or False, got {value!r}")
        interval = self.switch_interval_s
        if interval is not None and (isinstance(interval, bool) or not isinstance(interval, float | int)
                                     or not 1e-5 <= interval <= 0.1):
            raise ParameterError(
                f"RealtimeConfig.switch_interval_s must be in [1e-5, 0.1] s, got {interval!r}"
            )


@dataclass(frozen=True)
class RealtimeReport:
    """What was applied, and what the OS refused (with why).

    Parameters
    ----------
    applied
        The settings in effect, e.g. ``("SCHED_FIFO 50", "CPU 1")``.
    unavailable
        The settings asked for but not applied, each with the reason.
    """

    applied: tuple[str, ...]
    unavailable: tuple[str, ...]

    def describe(self) -> str:
        """One line for the run summary: what was applied, then what was not and why."""
        parts = list(self.applied) or ["none"]
        if self.unavailable:
            parts.append("unavailable: " + "; ".join(self.unavailable))
        return ", ".join(parts)


@contextmanager
def realtime(config: RealtimeConfig) -> Iterator[RealtimeReport]:
    """Apply ``config`` to the calling thread for the duration of the block (see the module).

    Parameters
    ----------
    config
        The settings to ask for.

    Yields
    ------
    RealtimeReport
        What was applied and what the OS refused; nothing refused raises.
    """
    applied: list[str] = []
    unavailable: list[str] = []
    with ExitStack() as restore:  # callbacks run last-in first-out, also when the block raises
        if config.freeze_gc:
            restore.callback(gc.collect)  # last, once the thread is back at its normal priority
        if config.priority is not None:
            _fifo(config.priority, restore, applied, unavailable)
        if config.cpus is not None:
            _affinity(config.cpus, restore, applied, unavailable)
        if config.lock_memory:
            _lock_memory(restore, applied, unavailable)
        if config.switch_interval_s is not None:
            restore.callback(sys.setswitchinterval, sys.getswitchinterval())
            sys.setswitchinterval(config.switch_interval_s)
            applied.append(f"switch interval {1e3 * config.switch_interval_s:g} ms")
        if config.freeze_gc:
            _freeze_gc(restore)
            applied.append("gc frozen, no collection in the loop")
        yield RealtimeReport(tuple(applied), tuple(unavailable))


@contextmanager
def at_normal_priority() -> Iterator[None]:
    """The calling thread under the normal policy for the block, its own after (a no-op where it was
    normal already, or the OS has no policies).

    For computations a real-time loop starts on a thread of its own (the bench's identification while
    it holds the arm): the thread inherits the loop's ``SCHED_FIFO``, and at that priority seconds of
    fitting took a core from the simulated devices' process until the load cell's reader timed out
    (a default `bench run` stopped on "load cell lost" after its 350 strokes, 2026-11-28). Threads
    it starts (a BLAS pool) inherit the normal policy too.
    """
    try:
        policy, priority = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
    except (AttributeError, OSError):
        yield
        return
    lowered = False
    if policy in _REALTIME_POLICIES:
        with suppress(OSError):
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
            lowered = True
    try:
        yield
    finally:
        if lowered:
            with suppress(OSError):  # lowering needs no privilege, raising back may
                os.sched_setscheduler(0, policy, os.sched_param(priority))


def _fifo(priority: int, restore: ExitStack, applied: list[str], unavailable: list[str]) -> None:
    if not hasattr(os, "sched_setscheduler"):
        unavailable.append("SCHED_FIFO: not offered by this OS")
        return
    try:
        policy, previous = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except OSError as error:
        unavailable.append(f"SCHED_FIFO: {_reason(error)} (needs root, CAP_SYS_NICE or an rtprio limit; "
                           "see docs/hardware.md)")
        return
    restore.callback(os.sched_setscheduler, 0, policy, os.sched_param(previous))
    applied.append(f"SCHED_FIFO {priority}")
    lifted = _lift_other_threads(priority, restore)
    if lifted:
        applied.append(f"SCHED_FIFO {priority} also for the process's {lifted} other Python "
                       f"thread{'s' if lifted > 1 else ''}")


def _lift_other_threads(priority: int, restore: ExitStack) -> int:
    """Give the process's other Python threads ``priority`` for the block; how many were lifted.

    On the way out each lifted thread gets its own policy back, and a thread started during the block
    (by the loop or a lifted thread: it inherited ``SCHED_FIFO``) gets the normal policy, so no thread
    outlives the block at real-time priority. Threads already real-time at the start are left alone.
    """
    own = threading.get_native_id()
    before: dict[int, tuple[int, int]] = {}
    for tid in _python_thread_ids(own):
        with suppress(OSError):  # it ended meanwhile (ESRCH)
            before[tid] = (os.sched_getscheduler(tid), os.sched_getparam(tid).sched_priority)
    lifted = [tid for tid, (policy, _) in before.items() if policy not in _REALTIME_POLICIES]
    for tid in lifted:
        try:
            os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority))
        except OSError:  # it ended, or the OS refused this one: the loop's own setting stands
            before.pop(tid)
    restore.callback(_unlift_threads, own, before)
    return sum(tid in before for tid in lifted)


def _unlift_threads(own: int, before: dict[int, tuple[int, int]]) -> None:
    for tid in _python_thread_ids(own):
        policy, priority = before.get(tid, (os.SCHED_OTHER, 0))
        with suppress(OSError):  # the thread has ended: nothing to restore
            if tid in before or os.sched_getscheduler(tid) == os.SCHED_FIFO:
                os.sched_setscheduler(tid, policy, os.sched_param(priority))


def _python_thread_ids(own: int) -> list[int]:
    """The native ids of the process's running Python threads but the calling one."""
    return [thread.native_id for thread in threading.enumerate()
            if thread.native_id is not None and thread.native_id != own and thread.is_alive()]


def _affinity(cpus: frozenset[int], restore: ExitStack, applied: list[str], unavailable: list[str]) -> None:
    shown = "{" + ", ".join(str(c) for c in sorted(cpus)) + "}"
    if not hasattr(os, "sched_setaffinity"):
        unavailable.append(f"CPU {shown}: affinity not offered by this OS")
        return
    try:
        previous = os.sched_getaffinity(0)
        os.sched_setaffinity(0, cpus)
    except OSError as error:
        allowed = ", ".join(str(c) for c in sorted(os.sched_getaffinity(0)))
        unavailable.append(f"CPU {shown}: {_reason(error)} (this thread may run on {{{allowed}}})")
        return
    restore.callback(os.sched_setaffinity, 0, previous)
    applied.append(f"CPU {shown}")


def _freeze_gc(restore: ExitStack) -> None:
    was_enabled, was_frozen = gc.isenabled(), gc.get_freeze_count() > 0
    gc.collect()  # garbage made before the run is freed, not frozen
    gc.freeze()
    gc.disable()

    def thaw() -> None:
        if not was_frozen:  # someone else's freeze (before ours) is theirs to undo
            gc.unfreeze()
        if was_enabled:
            gc.enable()

    restore.callback(thaw)


def _lock_memory(restore: ExitStack, applied: list[str], unavailable: list[str]) -> None:
    libc = _libc()
    if libc is None or not sys.platform.startswith("linux"):
        unavailable.append("memory lock: mlockall not offered by this OS")
        return
    if _locked_kib() > 0:
        unavailable.append("memory lock: the process already holds locked memory (left as it is)")
        return
    limit = _memlock_limit()
    if limit is not None and not _has_ipc_lock():
        # With MCL_FUTURE, an allocation past the limit would fail (MemoryError) in the middle of a run.
        unavailable.append(f"memory lock: the memlock limit is {limit // 1024} KiB (needs CAP_IPC_LOCK or "
                           "memlock unlimited; see docs/hardware.md)")
        return
    current, future = (0x2000, 0x4000) if platform.machine().startswith(("ppc", "powerpc", "sparc",
                                                                          "alpha")) else (1, 2)
    if libc.mlockall(current | future) != 0:
        reason = os.strerror(ctypes.get_errno()).lower()
        unavailable.append(f"memory lock: {reason} (needs CAP_IPC_LOCK or memlock unlimited; "
                           "see docs/hardware.md)")
        return
    restore.callback(libc.munlockall)
    applied.append(f"memory locked ({_locked_kib() // 1024} MiB)")


def _libc() -> ctypes.CDLL | None:
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name, use_errno=True)
        libc.mlockall.argtypes = [ctypes.c_int]
        libc.munlockall.argtypes = []
    except (OSError, AttributeError):
        return None
    return libc


def _proc_status(field: str) -> str | None:
    try:
        text = Path("/proc/self/status").read_text()
    except OSError:
        return None
    for line in text.splitlines():
        key, _, value = line.partition(":")
        if key == field:
            return value.strip()
    return None


def _locked_kib() -> int:
    value = _proc_status("VmLck")
    return int(value.split()[0]) if value else 0


def _has_ipc_lock() -> bool:
    value = _proc_status("CapEff")
    return value is not None and bool(int(value, 16) >> _CAP_IPC_LOCK & 1)


def _memlock_limit() -> int | None:
    """The soft RLIMIT_MEMLOCK in bytes, or None when unlimited."""
    import resource

    soft, _ = resource.getrlimit(resource.RLIMIT_MEMLOCK)
    return None if soft == resource.RLIM_INFINITY else soft


def _reason(error: OSError) -> str:
    return (error.strerror or str(error)).lower()
