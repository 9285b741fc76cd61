"""Real-time settings: applied where the OS allows, reported where not, always restored."""

from __future__ import annotations

import gc
import os
import sys

import pytest

from bowden.errors import ParameterError
from bowden.runtime.realtime import RealtimeConfig, realtime


def test_settings_inside_match_the_report_and_are_restored() -> None:
    policy, cpus, enabled = os.sched_getscheduler(0), os.sched_getaffinity(0), gc.isenabled()
    interval = sys.getswitchinterval()
    one_cpu = frozenset({min(cpus)})
    with realtime(RealtimeConfig(priority=10, cpus=one_cpu)) as report:
        fifo = os.sched_getscheduler(0) == os.SCHED_FIFO
        assert fifo == ("SCHED_FIFO 10" in report.applied)
        assert fifo != any(text.startswith("SCHED_FIFO") for text in report.unavailable)
        if fifo:
            assert os.sched_getparam(0).sched_priority == 10
        assert os.sched_getaffinity(0) == set(one_cpu)
        assert not gc.isenabled() and gc.get_freeze_count() > 0
        assert sys.getswitchinterval() == pytest.approx(0.0005)
        assert "gc frozen" in report.describe()
    assert os.sched_getscheduler(0) == policy
    assert os.sched_getaffinity(0) == cpus
    assert gc.isenabled() == enabled and gc.get_freeze_count() == 0
    assert sys.getswitchinterval() == interval


def test_restored_when_the_block_raises() -> None:
    policy = os.sched_getscheduler(0)
    with pytest.raises(RuntimeError, match="loop bug"), realtime(RealtimeConfig(priority=5)):
        raise RuntimeError("loop bug")
    assert os.sched_getscheduler(0) == policy and gc.isenabled()


def test_a_refused_setting_is_reported_not_raised() -> None:
    cpus = os.sched_getaffinity(0)
    absent = frozenset({max(cpus) + 64})  # no such CPU: the OS refuses the affinity
    with realtime(RealtimeConfig(priority=None, cpus=absent, freeze_gc=False,
                                 switch_interval_s=None)) as report:
        assert os.sched_getaffinity(0) == cpus
    assert report.applied == ()
    assert len(report.unavailable) == 1 and report.unavailable[0].startswith("CPU affinity")
    assert report.describe().startswith("none, unavailable: CPU affinity")


@pytest.mark.parametrize("kwargs", [{"priority": 0}, {"priority": 100}, {"priority": True},
                                    {"cpus": frozenset()}, {"cpus": frozenset({-1})},
                                    {"switch_interval_s": 1.0}])
def test_config_validation(kwargs: dict[str, object]) -> None:
    with pytest.raises(ParameterError, match="RealtimeConfig"):
        RealtimeConfig(**kwargs)  # type: ignore[arg-type]
