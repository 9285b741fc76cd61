"""Test-wide settings.

Property-based tests draw new examples on every run where developers run them, so they keep finding
bugs; CI (``HYPOTHESIS_PROFILE=ci``, set by ``.ci/run``) draws the same examples every time, so a
landing never depends on luck. Tests never assert on wall time, so the deadline is off.
"""

import os

import pytest
from hypothesis import settings

settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
settings.register_profile("dev", deadline=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "dev"))


# The suite runs on several worker processes (pyproject: -n auto --dist loadgroup). The tests that
# run the suit in real time share one group, run one after the other on one worker:
# - they drive the simulated suit (its own process, or peers on threads) on the wall clock at real-time
#   priority: two at once on a 2-core machine starve each other's devices (a simulated motor silent
#   for 31 ms is a real watchdog fault), which no test should have to tolerate;
# - LSL discovery sees every outlet on the machine (resolve scope machine), so two workers' streams of
#   the same name would reach each other's inlets.
# The other worker meanwhile runs the rest, at normal priority, which the real-time threads preempt.
SERIAL_GROUPS = {
    "realtime": (
        "tests/cli/test_bench_run_cli.py",
        "tests/cli/test_check.py",
        "tests/cli/test_run_custom.py",
        "tests/cli/test_run_lsl_imu.py",
        "tests/cli/test_run_registry.py",
        "tests/cli/test_suit.py",
        "tests/hardware/test_lsl_imu.py",
        "tests/hardware/test_motor_plugin.py",
        "tests/runtime/test_bench_full_disk.py",
        "tests/runtime/test_bench_protocol.py",
        "tests/runtime/test_bench_run_sim.py",
        "tests/runtime/test_bench_segments_sim.py",
        "tests/runtime/test_cli_full_disk.py",
        "tests/runtime/test_cli_run.py",
        "tests/runtime/test_host_stall.py",
        "tests/runtime/test_interrupt_signals.py",
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


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """``-n auto``: one worker more than the cores. The worker running the real-time group spends most
    of its time waiting on the wall clock (its devices' threads, at real-time priority, take what CPU
    they need first), so with one worker per core a core idled while the other ran everything else
    (measured: the rest is about 7 minutes of one core's CPU, the real-time group under 6 of wall)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return cores + 1


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    root = config.rootpath
    missing = [path for files in SERIAL_GROUPS.values() for path in files if not (root / path).exists()]
    if missing:  # a renamed test file would silently leave its group
        raise pytest.UsageError(f"tests/conftest.py's SERIAL_GROUPS names files that do not exist: {missing}")
    for item in items:
        path = item.path.relative_to(root).as_posix()
        for group, files in SERIAL_GROUPS.items():
            if path in files:
                item.add_marker(pytest.mark.xdist_group(group))
