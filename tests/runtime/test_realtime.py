"""Real-time settings: applied where the OS allows, reported where not, always restored.

The calls are real. Whether the OS grants ``SCHED_FIFO`` or a memory lock depends on the machine
(root, capabilities, limits), so the tests check that what the report says is what the OS says inside
the block, whichever it is, and a child process that gives up its privileges sees the refusals.
"""

from __future__ import annotations

import gc
import json
import os
import subprocess
import sys
import threading
import weakref

import pytest

from bowden.errors import ParameterError
from bowden.runtime.realtime import RealtimeConfig, RealtimeReport, at_normal_priority, realtime

NOTHING = {"priority": None, "freeze_gc": False, "switch_interval_s": None}


# Memory this process has locked in RAM, KiB (for the child processes' scripts).
LOCKED_KIB = """
def locked_kib():
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmLck:"):
                return int(line.split()[1])
    return 0
"""


def test_settings_inside_match_the_report_and_are_restored() -> None:
    policy, cpus, enabled = os.sched_getscheduler(0), os.sched_getaffinity(0), gc.isenabled()
    interval = sys.getswitchinterval()
    one_cpu = min(cpus)
    with realtime(RealtimeConfig(priority=10, cpus=frozenset({one_cpu}))) as report:
        fifo = os.sched_getscheduler(0) == os.SCHED_FIFO
        assert fifo == ("SCHED_FIFO 10" in report.applied)
        assert fifo != any(text.startswith("SCHED_FIFO") for text in report.unavailable)
        if fifo:
            assert os.sched_getparam(0).sched_priority == 10
        assert os.sched_getaffinity(0) == {one_cpu}
        assert f"CPU {{{one_cpu}}}" in report.applied
        assert not gc.isenabled() and gc.get_freeze_count() > 0
        assert sys.getswitchinterval() == pytest.approx(0.0005)
        assert "gc frozen, no collection in the loop" in report.applied
    assert os.sched_getscheduler(0) == policy
    assert os.sched_getaffinity(0) == cpus
    assert gc.isenabled() == enabled and gc.get_freeze_count() == 0
    assert sys.getswitchinterval() == interval


def test_restored_when_the_block_raises() -> None:
    policy, cpus, interval = os.sched_getscheduler(0), os.sched_getaffinity(0), sys.getswitchinterval()
    config = RealtimeConfig(priority=5, cpus=frozenset({max(cpus)}), lock_memory=False)
    with pytest.raises(RuntimeError, match="loop bug"), realtime(config):
        raise RuntimeError("loop bug")
    assert os.sched_getscheduler(0) == policy and os.sched_getaffinity(0) == cpus
    assert gc.isenabled() and gc.get_freeze_count() == 0
    assert sys.getswitchinterval() == interval


def _waiting_thread(stop: threading.Event) -> threading.Thread:
    thread = threading.Thread(target=stop.wait, daemon=True)
    thread.start()
    return thread


def test_the_other_python_threads_share_the_priority_for_the_block_only() -> None:
    # They share the interpreter lock with the loop: a normal thread holding it while preempted would
    # keep a real-time loop waiting (a priority inversion).
    stop = threading.Event()
    reader = _waiting_thread(stop)
    assert reader.native_id is not None
    try:
        with realtime(RealtimeConfig(priority=10, freeze_gc=False)) as report:
            if "SCHED_FIFO 10" not in report.applied:
                pytest.skip(f"the OS refuses SCHED_FIFO here: {report.unavailable}")
            assert os.sched_getscheduler(reader.native_id) == os.SCHED_FIFO
            assert os.sched_getparam(reader.native_id).sched_priority == 10
            assert any(text.startswith("SCHED_FIFO 10 also for the process's") for text in report.applied)
            started_inside = _waiting_thread(stop)  # inherits the loop thread's policy
            assert started_inside.native_id is not None
            assert os.sched_getscheduler(started_inside.native_id) == os.SCHED_FIFO
        # Back to normal, the one started inside the block too: no thread outlives it real-time.
        assert os.sched_getscheduler(reader.native_id) == os.SCHED_OTHER
        assert os.sched_getscheduler(started_inside.native_id) == os.SCHED_OTHER
    finally:
        stop.set()


def test_a_thread_already_real_time_keeps_its_own_priority() -> None:
    stop = threading.Event()
    device = _waiting_thread(stop)
    assert device.native_id is not None
    try:
        try:
            os.sched_setscheduler(device.native_id, os.SCHED_FIFO, os.sched_param(3))
        except PermissionError:
            pytest.skip("the OS refuses SCHED_FIFO here")
        with realtime(RealtimeConfig(priority=10, freeze_gc=False)):
            assert os.sched_getparam(device.native_id).sched_priority == 3
        assert os.sched_getscheduler(device.native_id) == os.SCHED_FIFO
        assert os.sched_getparam(device.native_id).sched_priority == 3
    finally:
        stop.set()


def test_a_computation_started_by_the_loop_runs_at_normal_priority() -> None:
    # The bench's identification runs on a thread the real-time loop starts, which inherits SCHED_FIFO;
    # at that priority it starved the simulated devices. It, and threads it starts, run normally.
    from concurrent.futures import ThreadPoolExecutor

    from bowden.runtime.bench_segments import _at_normal_priority

    def policies() -> tuple[int, int]:
        with ThreadPoolExecutor(max_workers=1) as pool:  # a pool the computation starts (a BLAS one)
            started = pool.submit(os.sched_getscheduler, 0).result()
        return os.sched_getscheduler(0), started

    with realtime(RealtimeConfig(priority=10, freeze_gc=False)) as report:
        if "SCHED_FIFO 10" not in report.applied:
            pytest.skip(f"the OS refuses SCHED_FIFO here: {report.unavailable}")
        with ThreadPoolExecutor(max_workers=1) as task_thread:
            assert task_thread.submit(os.sched_getscheduler, 0).result() == os.SCHED_FIFO  # inherited
            assert task_thread.submit(_at_normal_priority, policies).result() == (os.SCHED_OTHER,
                                                                                  os.SCHED_OTHER)
            # The thread has its inherited priority back for whatever it runs next.
            assert task_thread.submit(os.sched_getscheduler, 0).result() == os.SCHED_FIFO
        with at_normal_priority():
            assert os.sched_getscheduler(0) == os.SCHED_OTHER
        assert os.sched_getscheduler(0) == os.SCHED_FIFO and os.sched_getparam(0).sched_priority == 10


class _Node:
    def __init__(self) -> None:
        self.me = self  # a reference cycle: only the collector frees it


def test_no_collection_during_the_block_and_one_after() -> None:
    with realtime(RealtimeConfig(priority=None)):
        node = _Node()
        alive = weakref.ref(node)
        del node
        for _ in range(10_000):  # plenty of allocations: with collection on, gen 0 would run
            _Node().me = None
        assert alive() is not None
    assert alive() is None  # the collection after the block freed it


def test_a_freeze_made_before_is_left_alone() -> None:
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        with realtime(RealtimeConfig(priority=None)):
            assert gc.get_freeze_count() >= frozen
        assert gc.get_freeze_count() >= frozen > 0
    finally:
        gc.unfreeze()


def test_a_refused_setting_is_reported_not_raised() -> None:
    cpus = os.sched_getaffinity(0)
    absent = max(cpus) + 64  # no such CPU: the OS refuses the affinity
    with realtime(RealtimeConfig(cpus=frozenset({absent}), **NOTHING)) as report:  # type: ignore[arg-type]
        assert os.sched_getaffinity(0) == cpus
    assert report.applied == ()
    assert len(report.unavailable) == 1
    assert report.unavailable[0].startswith(f"CPU {{{absent}}}: invalid argument (this thread may run on {{")
    assert report.describe().startswith(f"none, unavailable: CPU {{{absent}}}: invalid argument")


def test_memory_lock_matches_the_report_and_is_undone() -> None:
    # In a child: locking a whole test process (every library it loaded) is heavier than needed.
    script = """
import json
from bowden.runtime.realtime import RealtimeConfig, realtime
before = locked_kib()
with realtime(RealtimeConfig(lock_memory=True, priority=None, freeze_gc=False, switch_interval_s=None)) as r:
    inside = locked_kib()
print(json.dumps({"before": before, "inside": inside, "after": locked_kib(),
                  "applied": r.applied, "unavailable": r.unavailable}))
"""
    result = _child(script)
    assert result["before"] == 0
    locked = any(text.startswith("memory locked") for text in result["applied"])
    assert locked == (result["inside"] > 0)
    assert locked != any(text.startswith("memory lock:") for text in result["unavailable"])
    assert result["after"] == 0


def test_without_privileges_the_refusals_are_reported() -> None:
    # The child drops root (when it has it) and lowers its limits: SCHED_FIFO and the memory lock
    # are then refused, unless the interpreter itself was given the capabilities (setcap).
    script = """
import json, os, resource
from bowden.runtime.realtime import RealtimeConfig, realtime  # before giving up root's file access
resource.setrlimit(resource.RLIMIT_RTPRIO, (0, 0))
resource.setrlimit(resource.RLIMIT_MEMLOCK, (65536, 65536))
if os.geteuid() == 0:
    os.setgid(65534)
    os.setuid(65534)
with realtime(RealtimeConfig(priority=10, lock_memory=True)) as r:
    fifo = os.sched_getscheduler(0) == os.SCHED_FIFO
    inside = locked_kib()
print(json.dumps({"fifo": fifo, "inside": inside, "applied": r.applied, "unavailable": r.unavailable,
                  "policy_after": os.sched_getscheduler(0)}))
"""
    result = _child(script)
    assert result["fifo"] == ("SCHED_FIFO 10" in result["applied"])
    assert (result["inside"] > 0) == any(text.startswith("memory locked") for text in result["applied"])
    assert result["policy_after"] != os.SCHED_FIFO
    if not result["fifo"]:
        assert any(text.startswith("SCHED_FIFO: operation not permitted (needs root, CAP_SYS_NICE")
                   for text in result["unavailable"]), result
    if result["inside"] == 0:
        assert any(text.startswith("memory lock: ") for text in result["unavailable"]), result
    assert "gc frozen, no collection in the loop" in result["applied"]


def _child(script: str) -> dict[str, object]:
    done = subprocess.run([sys.executable, "-c", LOCKED_KIB + script], capture_output=True, text=True,
                          timeout=120, check=False, cwd="/")
    assert done.returncode == 0, done.stderr
    result: dict[str, object] = json.loads(done.stdout)
    return result


def test_describe_is_one_line() -> None:
    report = RealtimeReport(("SCHED_FIFO 50", "CPU {1}", "gc frozen, no collection in the loop"),
                            ("memory lock: operation not permitted",))
    assert report.describe() == ("SCHED_FIFO 50, CPU {1}, gc frozen, no collection in the loop, "
                                 "unavailable: memory lock: operation not permitted")
    assert RealtimeReport((), ()).describe() == "none"
    assert "\n" not in report.describe()


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"priority": 0}, "priority"), ({"priority": 100}, "priority"), ({"priority": True}, "priority"),
    ({"priority": 50.0}, "priority"), ({"cpus": frozenset()}, "cpus"), ({"cpus": frozenset({-1})}, "cpus"),
    ({"cpus": {1}}, "cpus"), ({"freeze_gc": 1}, "freeze_gc"), ({"lock_memory": "yes"}, "lock_memory"),
    ({"switch_interval_s": 1.0}, "switch_interval_s"), ({"switch_interval_s": True}, "switch_interval_s"),
])
def test_config_validation(kwargs: dict[str, object], field: str) -> None:
    with pytest.raises(ParameterError, match=f"RealtimeConfig.{field} "):
        RealtimeConfig(**kwargs)  # type: ignore[arg-type]
