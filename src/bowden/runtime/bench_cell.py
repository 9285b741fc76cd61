"""The load cell's age on the bench: a sensor that stops answering stops the bench, a reader thread
the host does not schedule is a gap in the data.

The load cell is read in its own thread (:class:`bowden.hardware.ads1115.ADS1115LoadCell`), which
counts its read attempts (readings, I²C errors, malformed replies). On a busy host that thread can
go unscheduled for a quarter second while the bench's loop runs on (measured: a 251 ms old reading
with no I²C error, load average 6.7 on 2 cores). The reader's attempts are its heartbeat:

* the reading is old but the reader kept trying (three attempts or more since the reading): the
  sensor does not answer, which stops the bench (the reader also gives up on repeated I²C errors,
  ``failure``, which the bench reads first);
* the reading is old and the reader made no attempt either: the reader was starved (or its I²C
  transfer hangs). That is a gap in the data, not a dead sensor: the bench goes on, watching the
  tension through the TDU's torque instead, and a stroke recorded with a gap is run again. A reader
  idle longer than ``load_cell_reader_max_idle_s`` stops the bench, naming the host or the bus.

A tension sensor without attempt counters is judged by its reading's age alone, as before.
"""

from __future__ import annotations

import logging
import math

from bowden.hardware.protocols import TensionSample, TensionSensor
from bowden.runtime.bench_config import BenchFault

_log = logging.getLogger(__name__)
# Failed attempts since the newest reading that make a sensor fault (the ADS1115 reader's own
# max_consecutive_errors); fewer, with the reader then starved, are a gap.
_FAILED_ATTEMPTS = 3


def reader_attempts(cell: TensionSensor) -> int | None:
    """How many reads the load cell's reader has attempted (None: it does not count them)."""
    counters = getattr(cell, "counters", None)
    try:
        return int(counters.samples + counters.io_errors + counters.malformed)  # type: ignore[union-attr]
    except (AttributeError, TypeError):
        return None


class LoadCellWatch:
    """Judges the load cell's newest reading by its age and its reader's heartbeat.

    Parameters
    ----------
    max_age_s
        A reading older than this (counted from a host stall's end at most) is missing.
    reader_max_idle_s
        A reader that has attempted nothing for this long stops the bench.
    """

    def __init__(self, max_age_s: float, reader_max_idle_s: float) -> None:
        self.max_age_s = max_age_s
        self.reader_max_idle_s = reader_max_idle_s
        self._attempts: int | None = None
        self._heartbeat_s = -math.inf  # when the bench last saw the reader's attempts advance
        self._taken_s = math.nan  # when the newest reading was taken
        self._attempts_at_reading: int | None = None  # the reader's attempts when it was first seen
        self.gaps = 0  # gaps in the data so far (a starved reader)
        self.in_gap = False

    def read(self, cell: TensionSensor, now: float, stall_end_s: float) -> tuple[TensionSample | None, bool]:
        """The newest reading (None before the first) and whether it is fresh (False: a gap, the
        reader starved).

        Raises
        ------
        BenchFault
            A sensor its reader tries and fails to read, or a reader idle beyond its limit.
        """
        # The attempts first: a reader that comes back between the two reads has then counted no
        # attempt whose reading this cycle missed.
        attempts = reader_attempts(cell)
        reading = cell.read()
        taken_s = reading.time_s if reading is not None else -math.inf
        if taken_s != self._taken_s:
            self._taken_s = taken_s
            self._attempts_at_reading = attempts
        if attempts is not None and attempts != self._attempts:
            self._attempts = attempts
            self._heartbeat_s = now
        age = now - max(taken_s, stall_end_s)
        if age <= self.max_age_s:
            self.in_gap = False
            return reading, True
        limit = f"limit {1e3 * self.max_age_s:.0f} ms"
        if attempts is None or self._attempts_at_reading is None:
            raise BenchFault(f"load cell: no reading for {1e3 * age:.0f} ms ({limit})")
        # Attempts since the reading, less the reading's own (counted after its sample is stored).
        failed = attempts - self._attempts_at_reading - 1
        if failed >= _FAILED_ATTEMPTS:
            raise BenchFault(f"load cell: no reading for {1e3 * age:.0f} ms ({limit}) while its reader "
                             f"tried at least {failed} times: the sensor does not answer (check its "
                             "wiring)")
        idle = now - max(self._heartbeat_s, stall_end_s)
        if idle > self.reader_max_idle_s:
            raise BenchFault(f"load cell: its reader has not run for {1e3 * idle:.0f} ms (limit "
                             f"{1e3 * self.reader_max_idle_s:.0f} ms): the host is too busy, or the I²C "
                             "bus hangs")
        if not self.in_gap:
            self.in_gap = True
            self.gaps += 1
            _log.warning("bench: the load cell's reader has not run for %.0f ms (host load): a gap in "
                         "the data", 1e3 * idle)
        return reading, False
