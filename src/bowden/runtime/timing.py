"""Loop-timing accounting: wake-up lateness histogram, deadline misses, skipped cycles.

Definitions (all on the loop's clock):

* **lateness** of a cycle = time it started − its scheduled start (≥ 0: the clock never wakes early);
* a **deadline miss** = a cycle whose command went out after the next cycle's scheduled start (its
  effect came a whole period late), plus every cycle skipped because the loop fell that far behind.

Recording is allocation-free: a fixed histogram of 10 µs bins, so it can sit in the hot path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

BIN_S = 1e-5
MAX_TRACKED_S = 0.1  # lateness beyond this goes to the last bin


@dataclass(frozen=True)
class TimingSummary:
    """Loop timing over a run (seconds; percentiles have the histogram's 10 µs resolution)."""

    rate_hz: float
    cycles: int
    deadline_misses: int
    skipped_cycles: int
    worst_lateness_s: float
    mean_lateness_s: float
    p50_lateness_s: float
    p99_lateness_s: float
    p999_lateness_s: float

    @property
    def miss_fraction(self) -> float:
        """Deadline misses (including skipped cycles) per scheduled cycle."""
        scheduled = self.cycles + self.skipped_cycles
        return self.deadline_misses / scheduled if scheduled else 0.0

    def describe(self) -> str:
        """One line for the run summary."""
        return (
            f"{self.cycles} cycles at {self.rate_hz:g} Hz: {self.deadline_misses} deadline misses "
            f"({100.0 * self.miss_fraction:.2f} %, {self.skipped_cycles} skipped), lateness p50 "
            f"{self.p50_lateness_s * 1e6:.0f} µs, p99 {self.p99_lateness_s * 1e6:.0f} µs, "
            f"worst {self.worst_lateness_s * 1e3:.2f} ms"
        )


class LoopTiming:
    """Accumulates cycle timing for one run at ``rate_hz``."""

    def __init__(self, rate_hz: float) -> None:
        self.rate_hz = rate_hz
        self.period_s = 1.0 / rate_hz
        self._bins = [0] * (int(MAX_TRACKED_S / BIN_S) + 1)
        self._last_bin = len(self._bins) - 1
        self.cycles = 0
        self.deadline_misses = 0
        self.skipped_cycles = 0
        self.worst_lateness_s = 0.0
        self._sum_lateness_s = 0.0

    def record(self, lateness_s: float, finished_late: bool) -> None:
        """One cycle: how late it woke, and whether its command went out after the next deadline."""
        if lateness_s < 0.0:
            lateness_s = 0.0
        index = int(lateness_s / BIN_S)
        self._bins[index if index < self._last_bin else self._last_bin] += 1
        self.cycles += 1
        self._sum_lateness_s += lateness_s
        if lateness_s > self.worst_lateness_s:
            self.worst_lateness_s = lateness_s
        if finished_late:
            self.deadline_misses += 1

    def skip(self, cycles: int) -> None:
        """``cycles`` scheduled cycles that never ran (the loop fell behind by whole periods)."""
        self.skipped_cycles += cycles
        self.deadline_misses += cycles

    def percentile_s(self, fraction: float) -> float:
        """Lateness below which ``fraction`` of the cycles fall (upper edge of its 10 µs bin)."""
        if self.cycles == 0:
            return math.nan
        target = fraction * self.cycles
        running = 0
        for index, count in enumerate(self._bins):
            running += count
            if running >= target:
                return (index + 1) * BIN_S
        return MAX_TRACKED_S

    def histogram(self) -> list[tuple[float, int]]:
        """Non-empty bins as (lower edge s, count)."""
        return [(index * BIN_S, count) for index, count in enumerate(self._bins) if count]

    def summary(self) -> TimingSummary:
        """The figures of the run so far."""
        return TimingSummary(
            rate_hz=self.rate_hz,
            cycles=self.cycles,
            deadline_misses=self.deadline_misses,
            skipped_cycles=self.skipped_cycles,
            worst_lateness_s=self.worst_lateness_s,
            mean_lateness_s=self._sum_lateness_s / self.cycles if self.cycles else math.nan,
            p50_lateness_s=self.percentile_s(0.5),
            p99_lateness_s=self.percentile_s(0.99),
            p999_lateness_s=self.percentile_s(0.999),
        )
