"""The loop's pace: absolute deadlines, host stalls, and the timing account.

Deadlines are ``t₀ + k/rate`` of the injected clock, computed afresh each cycle so rounding never
accumulates; a late cycle does not delay the next deadline, and when the loop falls behind by whole
periods it skips to the next deadline and counts the skipped cycles as misses. A *host stall* is the
time the loop itself was not scheduled (the gap since the previous cycle began, beyond one period).
"""

from __future__ import annotations

from bowden.hardware.protocols import Clock
from bowden.runtime.timing import LoopTiming

STALL_NOTICE_S = 0.01
"""A gap between cycles this much longer than the period counts (and is recorded) as a host stall."""


class Pacer:
    """Wakes the loop on its deadlines and accounts for how well it kept them.

    Attributes
    ----------
    t0
        Clock time of the first deadline (loop time zero).
    stall_s
        The host stall measured at the latest wake-up (≤ 0: none).
    host_stalls, worst_stall_s
        Stalls over :data:`STALL_NOTICE_S` so far, and the longest.
    fresh_since
        Clock time of the latest noticed stall (or ``t0``): a sensor sample's age counts from here at
        most, because the loop could not have read it earlier.
    """

    __slots__ = ("_clock", "_deadline", "_k", "_last_wake", "_period", "_timing", "_woke",
                 "fresh_since", "host_stalls", "stall_s", "t0", "worst_stall_s")

    def __init__(self, clock: Clock, timing: LoopTiming) -> None:
        self._clock = clock
        self._timing = timing
        self._period = timing.period_s
        self.t0 = self._deadline = self._woke = self.fresh_since = 0.0
        self._last_wake = -self._period
        self._k = 0
        self.stall_s = self.worst_stall_s = 0.0
        self.host_stalls = 0

    def start(self, t0: float) -> None:
        """Loop time zero at clock time ``t0``: the first deadline."""
        self.t0 = self._deadline = self.fresh_since = t0
        self._last_wake = t0 - self._period
        self._k = 0

    def wait(self) -> float:
        """Sleep until the deadline; the clock time of waking. Notes a host stall."""
        self._clock.sleep_until(self._deadline)
        now = self._woke = self._clock.now()
        stall = self.stall_s = now - self._last_wake - self._period
        self._last_wake = now
        if stall > STALL_NOTICE_S:
            self.host_stalls += 1
            self.fresh_since = now
            if stall > self.worst_stall_s:
                self.worst_stall_s = stall
        return now

    def cycle_done(self, end: float) -> None:
        """The cycle that woke last sent its command at clock time ``end``."""
        deadline = self._deadline
        self._timing.record(self._woke - deadline, end > deadline + self._period)

    def advance(self) -> None:
        """On to the next deadline, skipping (and counting) those already past by a whole period."""
        period = self._period
        self._k += 1
        self._deadline = self.t0 + self._k * period
        behind = self._clock.now() - self._deadline
        if behind > period:
            skipped = int(behind / period)
            self._k += skipped
            self._deadline = self.t0 + self._k * period
            self._timing.skip(skipped)
