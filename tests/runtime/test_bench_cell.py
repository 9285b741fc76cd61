"""The bench's judgement of the load cell's age (issue 26, item 7): a reader the host starves is a gap
in the data, a sensor its reader cannot read stops the bench, a reader idle too long stops it naming
the host."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from bowden.hardware.ads1115 import ADS1115Counters
from bowden.runtime.bench_cell import LoadCellWatch, reader_attempts
from bowden.runtime.bench_config import BenchFault

LIMIT_S, IDLE_S = 0.25, 1.0


def cell(samples: int = 0, io_errors: int = 0) -> SimpleNamespace:
    return SimpleNamespace(counters=ADS1115Counters(samples=samples, io_errors=io_errors))


def test_a_fresh_reading_is_fresh():
    watch = LoadCellWatch(LIMIT_S, IDLE_S)
    assert watch.fresh(cell(10), reading_time_s=9.9, now=10.0, stall_end_s=0.0)
    assert watch.gaps == 0


def test_a_reader_that_makes_no_attempt_is_a_gap_counted_once_until_it_reads_again():
    watch, starved = LoadCellWatch(LIMIT_S, IDLE_S), cell(10)
    assert watch.fresh(starved, 10.0, 10.0, 0.0)  # its last attempt: the reading at 10 s
    for now in (10.3, 10.5, 10.9):  # no attempt since: not the sensor's fault
        assert not watch.fresh(starved, 10.0, now, 0.0)
    assert watch.gaps == 1
    starved.counters.samples += 1
    assert watch.fresh(starved, 10.95, 10.95, 0.0)
    assert not watch.fresh(starved, 10.95, 11.3, 0.0)
    assert watch.gaps == 2


def test_a_reader_that_keeps_trying_without_a_reading_is_the_sensor():
    watch, failing = LoadCellWatch(LIMIT_S, IDLE_S), cell(10)
    watch.fresh(failing, 10.0, 10.0, 0.0)
    failing.counters.io_errors += 2  # attempts, none of them a reading
    with pytest.raises(BenchFault, match=r"no reading for 300 ms \(limit 250 ms\) while its reader kept "
                                         "trying: the sensor does not answer"):
        watch.fresh(failing, 10.0, 10.3, 0.0)


def test_a_reader_idle_beyond_its_limit_stops_the_bench_naming_the_host():
    watch, starved = LoadCellWatch(LIMIT_S, IDLE_S), cell(10)
    watch.fresh(starved, 10.0, 10.0, 0.0)
    assert not watch.fresh(starved, 10.0, 10.9, 0.0)
    with pytest.raises(BenchFault, match=r"its reader has not run for 1100 ms \(limit 1000 ms\): the host "
                                         "is too busy, or the I²C bus hangs"):
        watch.fresh(starved, 10.0, 11.1, 0.0)


def test_ages_count_from_a_host_stall_and_a_sensor_without_counters_is_judged_by_age_alone():
    watch = LoadCellWatch(LIMIT_S, IDLE_S)
    assert watch.fresh(cell(10), 10.0, 10.4, stall_end_s=10.3)  # the whole process stood still
    assert reader_attempts(SimpleNamespace()) is None
    with pytest.raises(BenchFault, match=r"^load cell: no reading for 300 ms \(limit 250 ms\)$"):
        LoadCellWatch(LIMIT_S, IDLE_S).fresh(SimpleNamespace(), 10.0, 10.3, 0.0)
    assert LoadCellWatch(LIMIT_S, IDLE_S).fresh(SimpleNamespace(), -math.inf, 0.1, 0.0)  # none yet
