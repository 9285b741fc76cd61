"""Test-wide settings.

Property-based tests draw new examples on every run where developers run them, so they keep finding
bugs; CI (``HYPOTHESIS_PROFILE=ci``, set by ``.ci/run``) draws the same examples every time, so a
landing never depends on luck. Tests never assert on wall time, so the deadline is off.
"""

import os
import subprocess
import sys
from typing import Any

import pytest
from hypothesis import settings

settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
settings.register_profile("dev", deadline=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "dev"))


# The suite runs on several worker processes (pyproject: -n auto). The tests that run the suit or the
# bench in real time form one lane, run on one worker, one test after the other:
# - they drive the simulated devices (their own process, or peers on threads) on the wall clock under
#   SCHED_FIFO where the OS allows (the loops at bowden run's 50, the devices' process at 40): at most
#   one such test at a time keeps what they need within two cores, so no other test's load (the rest
#   runs at normal priority, which they preempt) can starve a simulated device, and none starves
#   another's. Two lanes at once did, on a two-core machine half as fast as before (2026-11-28: in CI a
#   motor peer silent for 118 ms; in a fresh clone's run a resumed bench's load cell, its I²C server
#   starved by the other lane's real-time loop: "3 I²C errors in a row over 40 ms");
# - LSL discovery sees every outlet on the machine (resolve scope machine), so two workers' streams of
#   the same name would reach each other's inlets: one lane keeps the LSL tests apart too.
# The rest runs beside the lane on the other workers.
SERIAL_GROUPS = {
    "real time": (  # the mannequin bench, then the suit, its console and LSL
        "tests/cli/test_bench_run_cli.py",
        "tests/runtime/test_bench_fit_sim.py",
        "tests/runtime/test_bench_full_disk.py",
        "tests/runtime/test_bench_protocol.py",
        "tests/runtime/test_bench_run_sim.py",
        "tests/runtime/test_bench_segments_sim.py",
        "tests/runtime/test_interrupt_signals.py",
        "tests/cli/test_check.py",
        "tests/cli/test_run_custom.py",
        "tests/cli/test_run_lsl_imu.py",
        "tests/cli/test_run_registry.py",
        "tests/cli/test_suit.py",
        "tests/hardware/test_lsl_imu.py",
        "tests/hardware/test_motor_plugin.py",
        "tests/runtime/test_cli_full_disk.py",
        "tests/runtime/test_cli_run.py",
        "tests/runtime/test_host_stall.py",
        "tests/runtime/test_lsl_run.py",
        "tests/runtime/test_realtime.py",
        "tests/runtime/test_run_trigger_report.py",
        "tests/runtime/test_slack_take_up.py",
        "tests/runtime/test_watchdogs.py",
        "tests/share/test_bids_recorded_run.py",
        "tests/sim/test_link_can_bus.py",
        "tests/sim/test_suit_process.py",
        "tests/study/test_real_study_docs.py",
        "tests/study/test_trial_traceability.py",
        "tests/web/test_browser_session.py",
        "tests/web/test_killed_server.py",
        "tests/web/test_preflight_route.py",
        "tests/web/test_real_suit.py",
        "tests/web/test_serve_sync.py",
        "tests/web/test_sim_devices.py",
    ),
}
_LANE_OF = {path: lane for lane, files in SERIAL_GROUPS.items() for path in files}
# Files whose tests share a session-scoped fixture (tests/study/reduced_study.py: a reduced study and its
# analyze --export): one unit of work, so that one worker builds it once, not each worker its own.
SHARED_FIXTURE_GROUPS = {
    "reduced study": (
        "tests/study/test_pipeline.py",
        "tests/share/test_r_script.py",
        "tests/share/test_bids_export.py",
        "tests/study/test_parallel_study.py",  # its single-process run (a process pool and Dask besides)
    ),
}
_UNIT_OF = {**_LANE_OF, **{path: group for group, files in SHARED_FIXTURE_GROUPS.items() for path in files}}
# Units that start processes of their own (R's refit, the BIDS validator, a process pool and a Dask
# cluster for the reduced study; a Dask cluster, a browser) wait until no lane runs
# (LaneScheduling._next_unit), then go first, the longest first. Beside the lane's real-time tests they
# cost them: handed out early, a resumed bench run stopped on "the IMU does not follow the arm" (two idle
# runs of three, 2026-11-27); the R refit and the validator beside the bench lane cost the later-segments
# bench test a quarter second in two fresh clones' runs of six (2026-11-28).
AFTER_THE_LANES = (
    "reduced study",
    "tests/sweep/test_runner.py",  # a Dask cluster
    "tests/sweep/test_cli.py",
    "tests/analysis/test_outcomes.py",
    "tests/web/test_browser.py",
    "tests/web/test_browser_check.py",
)


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """``-n auto``: one worker per core, at least one per lane. A third worker on an idle two-core
    machine (at nice 19, taking what the lane's wall-clock waits leave) saved about 40 s of five
    minutes on the faster machine of the ninth session, but it lost real-time tests in four of nine
    fresh clones' runs, and on the slower machine of the eleventh a warm idle run with it failed: the R
    refit timed out at nice 19 and the host-stall test's motor fell silent (docs/design.md "The
    tests"). It was removed in the twelfth session."""
    return _workers()


def _cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _workers() -> int:
    return max(_cores(), len(SERIAL_GROUPS))


def _worker_index(worker_id: str) -> int:
    """xdist's workers are named gw0, gw1, …"""
    return int(worker_id.removeprefix("gw"))


def _takes_lanes(worker_id: str) -> bool:
    """The first workers, one per lane, take the lanes; the others only the rest."""
    return _worker_index(worker_id) < len(SERIAL_GROUPS)


def _unit(nodeid: str) -> str:
    """The unit of work a test belongs to: its lane, its shared fixture's group, else its file (a
    file's tests share its module fixtures: spread over two workers, each would build them)."""
    path = nodeid.split("::", 1)[0]
    return _UNIT_OF.get(path, path)


def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object:
    """Each lane one unit of work for one worker, each shared-fixture group another, every other file
    its own; units are handed out in collection order (:func:`pytest_collection_modifyitems`), but
    those that start processes or a browser only when no lane runs (``LaneScheduling._next_unit``).

    xdist's own ``--dist loadgroup`` marks a group by rewriting the test's ``_nodeid``, which pytest 9.2
    no longer reads (``nodeid`` comes from ``_id``): the groups were silently spread over every worker.
    Scheduling by the file's unit does not depend on that."""
    from xdist.scheduler import LoadScopeScheduling

    config.option.loadscopereorder = False  # xdist's order (most tests first) would not put lanes first

    class LaneScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return _unit(nodeid)

        def schedule(self) -> None:
            # The first hand-out gives each worker one unit in the order of self.nodes (the order the
            # workers finished collecting): put the lane workers first, so that they take the lanes,
            # which lead the queue.
            if self.collection is None:
                self.assigned_work = dict(sorted(
                    self.assigned_work.items(), key=lambda item: _worker_index(item[0].gateway.id)))
            super().schedule()

        def mark_test_complete(self, node: Any, item_index: int, duration: float = 0) -> None:
            super().mark_test_complete(node, item_index, duration)  # reschedules ``node``
            for other in self.nodes:  # a worker left waiting for the lanes (_next_unit) may go on
                if other is not node:
                    self._reschedule(other)

        def _reschedule(self, node: Any) -> None:
            # xdist's own, but the unit is chosen (_next_unit), and a worker may be left waiting.
            if node.shutting_down:
                return
            if not self.workqueue:
                node.shutdown()
                return
            if self._pending_of(self.assigned_work[node]) > 2:  # xdist's: "almost depleted"
                return
            unit = self._next_unit(node)
            if unit is not None:
                self.workqueue.move_to_end(unit, last=False)
                self._assign_work_unit(node)

        def _next_unit(self, node: Any) -> str | None:
            """While another worker's lane runs, no unit of AFTER_THE_LANES (None: this worker
            waits, and is asked again when any test completes). Once no lane runs, those units go
            first: they are the longest (at the queue's end one ran alone for 30 s)."""
            queue: list[str] = list(self.workqueue)
            if queue[0] in SERIAL_GROUPS:  # a lane not handed out yet (fewer workers than lanes)
                return queue[0]
            if not self._lane_runs_beside(node):
                return next((unit for unit in queue if unit in AFTER_THE_LANES), queue[0])
            return next((unit for unit in queue if unit not in AFTER_THE_LANES), None)

        def _lane_runs_beside(self, node: Any) -> bool:
            """Whether another worker still has a lane's tests to run. One that holds only its last
            test is waiting for more work (xdist's worker runs a test once it knows the next one),
            so it does not count: two such workers would wait for each other."""
            for other, work in self.assigned_work.items():
                lane_left = sum(list(tests.values()).count(False)
                                for unit, tests in work.items() if unit in SERIAL_GROUPS)
                if other is not node and lane_left and self._pending_of(work) >= 2:
                    return True
            return False

    return LaneScheduling(config, log)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The lanes' tests first, then the rest in collection order, then the files that start processes
    or a browser (the same order on every worker: xdist checks that the collections agree)."""
    lanes = tuple(SERIAL_GROUPS)

    def rank(item: pytest.Item) -> int:
        unit = _unit(item.nodeid)
        if unit in lanes:
            return lanes.index(unit)
        return len(lanes) + 1 + AFTER_THE_LANES.index(unit) if unit in AFTER_THE_LANES else len(lanes)

    items.sort(key=rank)  # stable: within a unit, the collection's order


def pytest_sessionstart(session: pytest.Session) -> None:
    """Compile the simulated suit's kernels once, before the workers start (xdist starts them after
    this hook). On a fresh checkout every worker compiled them at once, beside the lanes' first
    real-time tests; the one failure of a fresh clone's run on 2026-11-27 came then (a resumed bench
    run's IMU apart from the mannequin's joint), and a starved start is the likely cause.

    The study's kernels (a trial simulated, encoded, analysed) are compiled in the background at the
    lowest priority (tests/warm_kernels.py): on a fresh checkout the suit lane's first analysis
    compiled them, in the lane whose wall time is the suite's."""
    if hasattr(session.config, "workerinput"):  # a worker: the controller has filled numba's cache
        return
    from bowden.sim.arm import MannequinArm, PrescribedArm
    from bowden.sim.peers.warm_up import warm_up_suit

    warm_up_suit(MannequinArm(load_torque_nm=1.0))  # the bench's mannequin
    warm_up_suit(PrescribedArm.hold(0.0))  # the suit's arm
    if session.config.getoption("numprocesses", None):  # workers: the study's kernels, in the background
        _STUDY_WARM_UP.append(subprocess.Popen(
            [sys.executable, str(session.config.rootpath / "tests" / "warm_kernels.py")],
            cwd=session.config.rootpath, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
            preexec_fn=lambda: os.nice(19),  # only what the lanes leave of the CPU
        ))


_STUDY_WARM_UP: list[subprocess.Popen[bytes]] = []


def pytest_sessionfinish(session: pytest.Session) -> None:
    for process in _STUDY_WARM_UP:  # done long before the suite ends, unless the host was busy
        if process.poll() is None:
            process.kill()
        _, error = process.communicate()
        if process.returncode > 0:  # it costs only time, but say so: a renamed function broke it
            print(f"\ntests/warm_kernels.py failed:\n{error.decode(errors='replace')}", file=sys.stderr)


def pytest_runtest_setup(item: pytest.Item) -> None:
    worker = getattr(item.config, "workerinput", {}).get("workerid")
    if not worker or _takes_lanes(worker):
        return
    if _unit(item.nodeid) in SERIAL_GROUPS:
        pytest.fail(f"a real-time lane's test was handed to worker {worker}, which takes no lane")


def pytest_configure(config: pytest.Config) -> None:
    files = [unit for unit in AFTER_THE_LANES if unit not in SHARED_FIXTURE_GROUPS]
    missing = [path for path in (*_UNIT_OF, *files) if not (config.rootpath / path).exists()]
    if missing:  # a renamed test file would silently leave its lane
        raise pytest.UsageError("tests/conftest.py names files that do not exist (SERIAL_GROUPS, "
                                f"SHARED_FIXTURE_GROUPS, AFTER_THE_LANES): {missing}")
