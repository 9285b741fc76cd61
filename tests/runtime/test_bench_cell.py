"""The bench's judgement of the load cell's age (issue 26, item 7): a reader the host starves is a gap
in the data, a sensor its reader cannot read stops the bench, a reader idle too long stops it naming
the host."""

from __future__ import annotations

import math

import pytest

from bowden.hardware.ads1115 import ADS1115Counters
from bowden.hardware.protocols import TensionSample
from bowden.runtime.bench_cell import LoadCellWatch, reader_attempts
from bowden.runtime.bench_config import BenchFault

LIMIT_S, IDLE_S = 0.25, 1.0


class Cell:
    """A load cell as its reader leaves it: the newest sample, and the reader's counters."""

    def __init__(self) -> None:
        self.counters = ADS1115Counters()
        self.sample: TensionSample | None = None

    def reads_at(self, time_s: float) -> None:  # as the reader: the sample, then the count
        self.sample = TensionSample(time_s, 10.0)
        self.counters.samples += 1

    def read(self) -> TensionSample | None:
        return self.sample


class Uncounted:
    def __init__(self, time_s: float) -> None:
        self.sample = TensionSample(time_s, 10.0) if math.isfinite(time_s) else None

    def read(self) -> TensionSample | None:
        return self.sample


def fresh(watch: LoadCellWatch, cell, now: float, stall_end_s: float = 0.0) -> bool:
    return watch.read(cell, now, stall_end_s)[1]


def test_a_fresh_reading_is_fresh():
    watch, cell = LoadCellWatch(LIMIT_S, IDLE_S), Cell()
    cell.reads_at(9.9)
    assert fresh(watch, cell, 10.0)
    assert watch.gaps == 0


def test_a_reader_that_makes_no_attempt_is_a_gap_counted_once_until_it_reads_again():
    watch, cell = LoadCellWatch(LIMIT_S, IDLE_S), Cell()
    cell.reads_at(10.0)
    assert fresh(watch, cell, 10.0)
    for now in (10.3, 10.5, 10.9):  # no attempt since: not the sensor's fault
        assert not fresh(watch, cell, now)
    assert watch.gaps == 1
    cell.reads_at(10.95)
    assert fresh(watch, cell, 10.95)
    assert not fresh(watch, cell, 11.3)
    assert watch.gaps == 2


def test_a_reader_back_from_starvation_is_not_taken_for_a_failing_sensor():
    # The reader stores its sample, then counts it: a bench that read the old sample and then the
    # new count called a reader back from 250 ms of starvation a sensor that does not answer.
    watch, cell = LoadCellWatch(LIMIT_S, IDLE_S), Cell()
    cell.reads_at(10.0)
    assert fresh(watch, cell, 10.0)
    cell.counters.samples += 1  # counted, the bench having read the sample before it was stored
    assert not fresh(watch, cell, 10.3)
    cell.sample = TensionSample(10.3, 10.0)
    assert fresh(watch, cell, 10.301)


def test_a_reader_that_keeps_trying_without_a_reading_is_the_sensor():
    watch, cell = LoadCellWatch(LIMIT_S, IDLE_S), Cell()
    cell.reads_at(10.0)
    watch.read(cell, 10.0, 0.0)
    cell.counters.io_errors += 4  # attempts, none of them a reading
    with pytest.raises(BenchFault, match=r"no reading for 300 ms \(limit 250 ms\) while its reader tried "
                                         "at least 3 times: the sensor does not answer"):
        watch.read(cell, 10.3, 0.0)


def test_a_reader_idle_beyond_its_limit_stops_the_bench_naming_the_host():
    watch, cell = LoadCellWatch(LIMIT_S, IDLE_S), Cell()
    cell.reads_at(10.0)
    watch.read(cell, 10.0, 0.0)
    assert not fresh(watch, cell, 10.9)
    with pytest.raises(BenchFault, match=r"its reader has not run for 1100 ms \(limit 1000 ms\): the host "
                                         "is too busy, or the I²C bus hangs"):
        watch.read(cell, 11.1, 0.0)


def test_ages_count_from_a_host_stall_and_a_sensor_without_counters_is_judged_by_age_alone():
    watch, cell = LoadCellWatch(LIMIT_S, IDLE_S), Cell()
    cell.reads_at(10.0)
    assert fresh(watch, cell, 10.4, stall_end_s=10.3)  # the whole process stood still
    assert reader_attempts(Uncounted(10.0)) is None
    with pytest.raises(BenchFault, match=r"^load cell: no reading for 300 ms \(limit 250 ms\)$"):
        LoadCellWatch(LIMIT_S, IDLE_S).read(Uncounted(10.0), 10.3, 0.0)
    assert fresh(LoadCellWatch(LIMIT_S, IDLE_S), Uncounted(-math.inf), 0.1)  # none yet, clock just started
