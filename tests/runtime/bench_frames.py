"""What the simulated bench's motors heard, read from its devices' process."""

from __future__ import annotations

import time
from typing import Any


def exited(backend: Any, since_s: float, expected: set[str], patience_s: float = 5.0) -> dict[str, float]:
    """When each simulated motor heard its exit frame after ``since_s``, waiting up to ``patience_s``
    for the ``expected`` ones: the driver does not wait for the exit's reply, so the devices' process
    may not have handled the frame yet when the run returns."""
    deadline = time.monotonic() + patience_s
    while True:
        times = {}
        for device in ("motor", "mannequin"):
            frames = [f.time_s for f in backend.simulation.received_frames(since_s, device)
                      if f.kind == "exit"]
            if frames:
                times[device] = frames[0]
        if expected <= times.keys() or time.monotonic() > deadline:
            return times
        time.sleep(0.01)
