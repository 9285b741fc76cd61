"""Clocks for the control loop (both implement :class:`bowden.hardware.Clock`).

:class:`MonotonicClock` is the real one: ``sleep_until`` waits for an absolute deadline, so a cycle
that wakes late does not push the next one later (no drift). The OS wakes a sleeping thread some tens
of microseconds late; ``spin_s`` trades CPU for precision by sleeping until shortly before the
deadline and spinning on the clock for the rest (0 by default: the machine is shared).

The simulated suit brings its own clock (``SimulatedSuit.clock``), whose ``sleep_until`` integrates
the physics to the deadline instead of waiting, so the same loop runs a simulated trial fast.
"""

from __future__ import annotations

import math
import time

from bowden.errors import ParameterError


class MonotonicClock:
    """Wall time from ``time.monotonic`` (s) with absolute-deadline sleeps.

    Parameters
    ----------
    spin_s
        Spin (busy-wait) for the last ``spin_s`` seconds before a deadline; 0 to only sleep.
    """

    def __init__(self, *, spin_s: float = 0.0) -> None:
        if not (math.isfinite(spin_s) and 0.0 <= spin_s <= 0.01):
            raise ParameterError(f"spin_s must be in [0, 0.01] s, got {spin_s!r}")
        self.spin_s = spin_s

    def now(self) -> float:
        return time.monotonic()

    def sleep_until(self, deadline_s: float) -> None:
        remaining = deadline_s - time.monotonic() - self.spin_s
        if remaining > 0.0:
            time.sleep(remaining)
        if self.spin_s > 0.0:
            while time.monotonic() < deadline_s:
                pass
