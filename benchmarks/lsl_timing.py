"""Late cycles of ``bowden run --backend sim`` with and without ``--lsl``, measured in one run.

Runs the same recorded trial alternately without and with the LSL outlets (and with an inlet in
another process pulling both streams, so the data really flows), ``--rounds`` times each, and prints
per run the loop-timing line of ``bowden run`` and, at the end, the deadline misses and p99 lateness
of each setting summed over its runs and their ratio. Discovery stays on this machine (an
``lsl_api.cfg`` with ``ResolveScope = machine`` through $LSLAPICFG).

    python benchmarks/lsl_timing.py [--duration 20] [--rounds 2] [--rate 500]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

_TIMING = re.compile(
    r"loop timing: (\d+) cycles at [\d.]+ Hz: (\d+) deadline misses .*?p99 (\d+) µs, worst ([\d.]+) ms"
)

# An inlet that pulls both streams until the trial-end marker, then quits.
_RECEIVER = """
import json, pylsl
inlets = [pylsl.StreamInlet(pylsl.resolve_byprop("name", name, timeout=120)[0])
          for name in ("bowden markers", "bowden loop")]
for inlet in inlets:
    inlet.open_stream(timeout=60)
done = False
while not done:
    inlets[1].pull_chunk(timeout=0.05)
    sample, _ = inlets[0].pull_sample(timeout=0.0)
    done = sample is not None and json.loads(sample[0])["event"] == "trial_end"
"""


def _run(
    directory: Path, env: dict[str, str], *, lsl: bool, duration_s: float, rate_hz: float
) -> tuple[int, ...]:
    store = directory / f"run-{len(list(directory.glob('*.db')))}.db"
    command = [
        sys.executable,
        "-m",
        "bowden",
        "run",
        "--backend",
        "sim",
        "--duration",
        str(duration_s),
        "--rate",
        str(rate_hz),
        "--condition",
        "support_50",
        "--record",
        str(store),
    ]
    receiver = None
    if lsl:
        command += ["--lsl", "--lsl-wait", "120"]
        receiver = subprocess.Popen([sys.executable, "-c", _RECEIVER], env=env, stderr=subprocess.DEVNULL)
    try:
        done = subprocess.run(command, env=env, capture_output=True, text=True, timeout=duration_s + 300)
    finally:
        if receiver is not None:
            try:
                receiver.wait(timeout=30)
            except subprocess.TimeoutExpired:
                receiver.kill()
    match = _TIMING.search(done.stdout)
    # Exit 3 is a watchdog's safe stop (on a loaded host, e.g. a late load-cell reading): its
    # cycles up to the stop still count, and the stop is printed.
    if done.returncode not in (0, 3) or match is None:
        raise SystemExit(f"bowden run failed ({done.returncode}):\n{done.stdout}\n{done.stderr}")
    line = next(text for text in done.stdout.splitlines() if text.startswith("loop timing"))
    print(f"{'with LSL   ' if lsl else 'without LSL'}  {line}", flush=True)
    if done.returncode == 3:
        print(f"             {done.stdout.splitlines()[0]}", flush=True)
    cycles, misses, p99_us, _worst = match.groups()
    return int(cycles), int(misses), int(p99_us)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=20.0, help="seconds per run (default 20)")
    parser.add_argument("--rounds", type=int, default=2, help="runs per setting, interleaved (default 2)")
    parser.add_argument("--rate", type=float, default=500.0, help="loop rate, Hz (default 500)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        directory = Path(folder)
        config = directory / "lsl_api.cfg"
        config.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n")
        env = {**os.environ, "LSLAPICFG": str(config)}
        totals = {False: [0, 0, 0], True: [0, 0, 0]}
        for _ in range(args.rounds):
            for lsl in (False, True):
                cycles, misses, p99 = _run(
                    directory, env, lsl=lsl, duration_s=args.duration, rate_hz=args.rate
                )
                total = totals[lsl]
                total[0] += cycles
                total[1] += misses
                total[2] = max(total[2], p99)
    print()
    for lsl in (False, True):
        cycles, misses, p99 = totals[lsl]
        print(
            f"{'with LSL   ' if lsl else 'without LSL'}  {misses} late of {cycles} cycles "
            f"({100.0 * misses / cycles:.3f} %), worst run's p99 lateness {p99} µs"
        )
    without, with_lsl = (totals[k][1] / totals[k][0] for k in (False, True))
    ratio = with_lsl / without if without > 0 else float("inf") if with_lsl > 0 else 1.0
    print(f"late-cycle fraction with / without LSL: {ratio:.2f}")


if __name__ == "__main__":
    main()
