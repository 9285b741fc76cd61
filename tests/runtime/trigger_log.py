"""A trigger 'line' for ``bowden run --trigger command:...``: appends ``LEVEL MONOTONIC_TIME`` to a file."""

import sys
import time

with open(sys.argv[1], "a", encoding="utf-8") as file:
    file.write(f"{sys.argv[2]} {time.monotonic()!r}\n")
