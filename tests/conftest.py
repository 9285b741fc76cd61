"""Test-wide settings.

Property-based tests draw new examples on every run where developers run them, so they keep finding
bugs; CI (``HYPOTHESIS_PROFILE=ci``, set by ``.ci/run``) draws the same examples every time, so a
landing never depends on luck. Tests never assert on wall time, so the deadline is off.
"""

import contextlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
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
    ),
}
_UNIT_OF = {**_LANE_OF, **{path: group for group, files in SHARED_FIXTURE_GROUPS.items() for path in files}}
# Files that start worker processes, a Dask cluster or a browser wait until no lane runs
# (LaneScheduling._next_unit), then go first: beside the lanes' real-time tests they cost them (handed
# out early on 2026-11-27, a resumed bench run stopped on "the IMU does not follow the arm" in two idle
# runs of three; at nice 19 on a third worker, 2026-11-28, an IMU 126 ms stale and a lost `bowden check`).
AFTER_THE_LANES = (
    "tests/study/test_parallel_study.py",  # a process pool and a Dask cluster (it makes its own reduced
    "tests/sweep/test_runner.py",  # study, about 5 s, on a worker that has not made one)
    "tests/sweep/test_cli.py",
    "tests/analysis/test_outcomes.py",
    "tests/web/test_browser.py",
    "tests/web/test_browser_check.py",
)
# Units that start one busy process of their own (R's refit, the BIDS validator) run beside a lane only
# on the low-priority worker, whose children inherit its priority: run by a lane's worker done with its
# lane, at normal priority, beside the bench lane, the later-segments bench test lost a quarter second
# in two fresh clones' runs of six (2026-11-28).
LOW_PRIORITY_BESIDE_THE_LANES = ("reduced study",)


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """``-n auto``: one worker per core, at least one per lane, and one more on a machine nothing else
    is using. A lane's tests run one after the other on one worker; they wait on the wall clock, so
    beside them the cores are partly idle (with the two lanes of the ninth session, CPU 132 % of 200 %
    in a fresh clone's 5 min 33 s run on 2026-11-28), which the extra worker takes for the rest.

    The extra worker runs at the lowest priority (:func:`pytest_configure`) and never takes a lane
    (:func:`pytest_xdist_make_scheduler`), so it has only what the lanes leave of the CPU. At normal
    priority it starved the lanes' devices: beside two busy processes four failures (the bench's IMU
    and controller and the recorder's writer), and on fresh clones, whose workers compile numba's
    kernels, two runs of two lost a real-time test (2026-11-28: a 112 ms host stall in a browser
    session, a silent mannequin seen 137 ms late). Beside busy processes there is nothing left to
    take, so there it is not started.

    Nor on a fresh checkout (numba's cache without the study's kernels), which is what CI runs. There,
    even at nice 19, it cost the later-segments bench test twice in six fresh clones' runs (the
    mannequin up to 23° off its reference, 2026-11-28), where two workers' fresh runs passed. In both,
    a lane's worker done with its lane had run the R refit and the BIDS validator beside the bench
    lane at normal priority; such units now wait (:func:`pytest_xdist_make_scheduler`), but of nine
    more fresh runs with it, four still lost a real-time test (a silent mannequin seen late, a fling
    0.1° past its bound, a load cell "lost" after 3 I²C errors in 40 ms, a trial's exit 3; docs/
    design.md "The tests"). A landing must not depend on luck; a developer's warm checkout gets the
    speed."""
    workers = _normal_workers()
    idle = _others_use_of_the_cores(_cores()) < IDLE_BELOW_CORES
    return workers + 1 if idle and _study_kernels_cached(config.rootpath) else workers


def _cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _normal_workers() -> int:
    """The workers at normal priority: one per core, at least one per lane (the extra one is not)."""
    return max(_cores(), len(SERIAL_GROUPS))


def _study_kernels_cached(root: Path) -> bool:
    """Whether numba's cache holds the batch simulator's trial kernel (a fresh checkout's does not)."""
    cache = os.environ.get("NUMBA_CACHE_DIR")
    folder = Path(cache) if cache else root / "src" / "bowden" / "sim" / "__pycache__"
    return folder.is_dir() and any(folder.rglob("_batch_kernel.run_trial-*.nbi"))


def _worker_index(worker_id: str) -> int:
    """xdist's workers are named gw0, gw1, …"""
    return int(worker_id.removeprefix("gw"))


def _takes_lanes(worker_id: str) -> bool:
    """The first workers, one per lane, take the lanes; the others only the rest."""
    return _worker_index(worker_id) < len(SERIAL_GROUPS)


def _low_priority(worker_id: str) -> bool:
    """The extra worker of an idle machine (:func:`pytest_xdist_auto_num_workers`), at nice 19. Not
    every worker that takes no lane: with one lane, the second worker of two is at normal priority
    (at nice 19 beside two busy processes it got 2 % of a core and had not collected the tests after
    five minutes, 2026-11-28)."""
    return _worker_index(worker_id) >= _normal_workers()


IDLE_BELOW_CORES = 0.25  # what other processes may use of the machine for it to count as idle


def _others_use_of_the_cores(cores: int, window_s: float = 0.5) -> float:
    """How many cores the machine's processes kept busy over ``window_s`` (Linux /proc/stat; elsewhere
    as many as there are, which says "not idle"). Measured now, not the load average: that lags a
    minute behind, and .ci/run starts the suite right after pip's install."""
    def busy_and_total() -> tuple[int, int]:
        with open("/proc/stat", encoding="ascii") as stat:
            # user nice system idle iowait irq softirq steal (guest time is already in user)
            ticks = [int(field) for field in stat.readline().split()[1:9]]
        idle = ticks[3] + ticks[4]  # idle, iowait
        return sum(ticks) - idle, sum(ticks)

    try:
        busy0, total0 = busy_and_total()
        time.sleep(window_s)
        busy1, total1 = busy_and_total()
    except (OSError, ValueError, IndexError):
        return float(cores)
    return cores * (busy1 - busy0) / max(total1 - total0, 1)


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

        lane_tests_left: set[str] | None = None

        def schedule(self) -> None:
            # The first hand-out gives each worker one unit in the order of self.nodes (the order the
            # workers finished collecting): put the lane workers first, so that they take the lanes,
            # which lead the queue, and a low-priority worker never does.
            if self.collection is None:
                self.assigned_work = dict(sorted(
                    self.assigned_work.items(), key=lambda item: _worker_index(item[0].gateway.id)))
                collection = next(iter(self.registered_collections.values()), [])
                self.lane_tests_left = {nodeid for nodeid in collection if _unit(nodeid) in SERIAL_GROUPS}
            super().schedule()

        def mark_test_complete(self, node: Any, item_index: int, duration: float = 0) -> None:
            super().mark_test_complete(node, item_index, duration)  # reschedules ``node``
            if self.lane_tests_left:
                self.lane_tests_left.discard(self.registered_collections[node][item_index])
                if not self.lane_tests_left:  # the low-priority worker may take its share now
                    Path(os.environ[_LANES_DONE]).touch()
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
            """While another worker's lane runs, no unit of AFTER_THE_LANES, and those of
            LOW_PRIORITY_BESIDE_THE_LANES only to the low-priority worker (None: this worker waits,
            and is asked again when any test completes). Once no lane runs, those units go first:
            they are the longest (at the queue's end one ran alone, niced, for 30 s)."""
            queue = list(self.workqueue)
            if queue[0] in SERIAL_GROUPS:  # a lane not handed out yet (fewer workers than lanes)
                return queue[0]
            if not self._lane_runs_beside(node):
                held_back = (*LOW_PRIORITY_BESIDE_THE_LANES, *AFTER_THE_LANES)
                return next((unit for unit in queue if unit in held_back), queue[0])
            low_priority = _low_priority(node.gateway.id)
            return next((unit for unit in queue if unit not in AFTER_THE_LANES and (
                low_priority or unit not in LOW_PRIORITY_BESIDE_THE_LANES)), None)

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
    for folder in _MADE:
        shutil.rmtree(folder, ignore_errors=True)
    for process in _STUDY_WARM_UP:  # done long before the suite ends, unless the host was busy
        if process.poll() is None:
            process.kill()
        _, error = process.communicate()
        if process.returncode > 0:  # it costs only time, but say so: a renamed function broke it
            print(f"\ntests/warm_kernels.py failed:\n{error.decode(errors='replace')}", file=sys.stderr)


# A file the controller creates once every lane's test is done (its path set before the workers start).
_LANES_DONE = "BOWDEN_TESTS_LANES_DONE"
_MADE: list[Path] = []  # the controller's folder for that file


def pytest_runtest_setup(item: pytest.Item) -> None:
    worker = getattr(item.config, "workerinput", {}).get("workerid")
    if not worker or _takes_lanes(worker):
        return
    if _unit(item.nodeid) in SERIAL_GROUPS:
        pytest.fail(f"a real-time lane's test was handed to worker {worker}, which takes no lane")
    lanes_done = Path(os.environ.get(_LANES_DONE, "")).is_file()
    if _low_priority(worker) and os.getpriority(os.PRIO_PROCESS, 0) > 0 and lanes_done:
        # The lanes are done: at the lowest priority beside two busy workers this one starved (an
        # EMG import's tests took 113 s instead of 25 s at the end of a fresh clone's run on a
        # loaded host, 2026-11-28). Back to normal priority where the user may (root or
        # CAP_SYS_NICE; checked by hand: gw2 at 19, then 0 at its first test after the lanes);
        # elsewhere it stays low.
        with contextlib.suppress(PermissionError):
            os.setpriority(os.PRIO_PROCESS, 0, 0)


def pytest_configure(config: pytest.Config) -> None:
    worker = getattr(config, "workerinput", {}).get("workerid")
    if worker and _low_priority(worker):
        os.nice(19)  # only what the lanes leave (see pytest_xdist_auto_num_workers); its children too
    if not worker and _LANES_DONE not in os.environ:  # the controller, before it starts the workers
        _MADE.append(Path(tempfile.mkdtemp(prefix="bowden-lanes-")))
        os.environ[_LANES_DONE] = str(_MADE[0] / "done")
    files = [unit for unit in AFTER_THE_LANES if unit not in SHARED_FIXTURE_GROUPS]
    missing = [path for path in (*_UNIT_OF, *files) if not (config.rootpath / path).exists()]
    if missing:  # a renamed test file would silently leave its lane
        raise pytest.UsageError("tests/conftest.py names files that do not exist (SERIAL_GROUPS, "
                                f"SHARED_FIXTURE_GROUPS, AFTER_THE_LANES): {missing}")
