"""False stops and host stalls of ``bowden run --backend sim`` with the default watchdogs.

Two measurements, each on the real command in a subprocess (the suit in its own process):

1. ``--runs`` runs of ``--duration`` seconds while ``--busy`` busy processes load the machine; counts
   the runs that stopped themselves (exit 3) and names their reasons. Goal (issue 14): 0 of 30 with
   four busy processes.
2. A SIGSTOP of the run's process for each of ``--pauses-ms`` (default 40, 90, 150 ms) in the middle of
   a run: the loop must tolerate stalls up to ``--host-stall-ms`` (100 ms) and stop with the host-stall
   reason beyond it.

    python benchmarks/host_stalls.py [--runs 30] [--busy 4] [--duration 6] [--pauses-ms 40 90 150]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator

RUN = [sys.executable, "-m", "bowden", "run", "--backend", "sim"]


@contextlib.contextmanager
def busy_processes(count: int) -> Iterator[None]:
    spinners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(count)]
    try:
        yield
    finally:
        for spinner in spinners:
            spinner.kill()
            spinner.wait()


def stop_line(stdout: str) -> str:
    return next((line for line in stdout.splitlines() if line.startswith("stopped:")), "no summary")


def health_line(stdout: str) -> str:
    return next((line for line in stdout.splitlines() if line.startswith("health:")), "")


def one_run(duration_s: float, pause_ms: float | None = None) -> tuple[int, str, str]:
    """Run once; with ``pause_ms``, SIGSTOP the run for that long once its loop has run 1 s."""
    process = subprocess.Popen([*RUN, "--duration", f"{duration_s:g}"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    running = threading.Event()
    errors: list[str] = []

    def watch_stderr() -> None:
        assert process.stderr is not None
        for line in process.stderr:
            errors.append(line)
            if line.startswith("t "):
                running.set()

    watcher = threading.Thread(target=watch_stderr, daemon=True)
    watcher.start()
    if pause_ms is not None and running.wait(timeout=300.0):
        time.sleep(0.5)
        os.kill(process.pid, signal.SIGSTOP)
        time.sleep(pause_ms / 1e3)
        os.kill(process.pid, signal.SIGCONT)
    assert process.stdout is not None
    stdout = process.stdout.read()  # stderr is the watcher's
    process.wait()
    watcher.join()
    text = stop_line(stdout)
    if process.returncode == 1:
        text = "".join(errors[-2:]).strip()
    return process.returncode, text, health_line(stdout)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--runs", type=int, default=30)
    parser.add_argument("--busy", type=int, default=4)
    parser.add_argument("--duration", type=float, default=6.0)
    parser.add_argument("--pauses-ms", type=float, nargs="*", default=[40.0, 90.0, 150.0])
    args = parser.parse_args(argv)

    print(f"1. {args.runs} runs of {args.duration:g} s beside {args.busy} busy processes")
    self_stops = 0
    with busy_processes(args.busy):
        for index in range(args.runs):
            code, text, health = one_run(args.duration)
            if code != 0:
                self_stops += 1
            print(f"   run {index + 1:2d}: exit {code}  {text}  | {health}", flush=True)
    print(f"   self-stops {self_stops} of {args.runs} (goal 0; ratio to the goal's bound of 0: "
          f"{'met' if self_stops == 0 else 'MISSED'})")

    print("2. SIGSTOP of the run's process (idle machine)")
    for pause in args.pauses_ms:
        code, text, health = one_run(args.duration, pause)
        expected = "HOST_STALL" if pause > 100.0 else "no fault"
        verdict = "as expected" if expected in text else "NOT as expected"
        print(f"   {pause:5.0f} ms: exit {code}  {text}  [{verdict}] | {health}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
