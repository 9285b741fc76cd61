"""Time from each injected fault to zero torque and to motor-mode exit, measured on the CAN frames.

Runs the fault tests of ``tests/runtime/test_watchdogs.py`` (default watchdogs, the simulated suit's
peers on the wire, a sniffer on the bus) ``--repeat`` times and prints, per fault, the worst latency
from the injection to the first zero-torque command frame and to the exit-motor-mode frame, with the
host's own share (the loop's worst lateness and stall in that run). Goal (issue 14): zero torque
≤ 80 ms and exit ≤ 100 ms for every fault.

    python benchmarks/faults.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

ZERO_GOAL_S = 0.080
EXIT_GOAL_S = 0.100


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    tests = Path(__file__).resolve().parent.parent / "tests" / "runtime" / "test_watchdogs.py"
    with tempfile.TemporaryDirectory() as directory:
        log = Path(directory) / "latencies.jsonl"
        env = dict(os.environ, BOWDEN_FAULT_LATENCIES=str(log))
        for _ in range(args.repeat):
            subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(tests)],
                           env=env, check=False, stdout=subprocess.DEVNULL)
        rows = [json.loads(line) for line in log.read_text().splitlines()]
    worst: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0, 0.0, 0.0])
    for row in rows:
        name = row["test"].split("::")[-1]
        entry = worst[name]
        entry[0] = max(entry[0], row["zero_s"])
        entry[1] = max(entry[1], row["exit_s"])
        entry[2] = max(entry[2], row["host_delay_s"])
        entry[3] += 1
    print(f"{'fault test':58s} {'runs':>4s} {'zero ms':>8s} {'/80':>5s} {'exit ms':>8s} {'/100':>5s} "
          f"{'host ms':>8s}")
    for name, (zero, exit_, host, runs) in sorted(worst.items()):
        print(f"{name:58s} {int(runs):4d} {1e3 * zero:8.1f} {zero / ZERO_GOAL_S:5.2f} {1e3 * exit_:8.1f} "
              f"{exit_ / EXIT_GOAL_S:5.2f} {1e3 * host:8.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
