"""Cost of the control loop's body per cycle, without the devices' or the clock's time.

The loop runs against in-memory devices (a motor that answers every command at once, an IMU and a
load cell that always have a fresh sample) on a clock whose ``sleep_until`` jumps to the deadline, so
the time per cycle is what the loop itself spends: reading, watchdogs, the controller's step,
sending, the recorder tap, pacing. With ``--against REV`` the same measurement also runs on the loop
of git revision REV (checked out into a temporary worktree), interleaved with this tree's, and the
ratio is printed (issue 32: the loop split into named steps must not cost its timing).

    python benchmarks/loop_body.py [--cycles 50000] [--repeats 7] [--against REV]
"""

from __future__ import annotations

import argparse
import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def measure(cycles: int) -> float:
    """Seconds per cycle of one run of ``cycles`` cycles (imports the bowden on sys.path)."""
    from bowden.control import build_controller
    from bowden.hardware.protocols import ElevationSample, MotorState, TensionSample
    from bowden.model import CompensationModel, Subject
    from bowden.runtime import ControlLoop, LoopConfig

    class JumpClock:
        def __init__(self) -> None:
            self.t = 0.0

        def now(self) -> float:
            return self.t

        def sleep_until(self, deadline_s: float) -> None:
            if deadline_s > self.t:
                self.t = deadline_s

    clock = JumpClock()

    class Motor:
        def enable(self) -> MotorState:
            return MotorState(0.0, 0.0, 0.0, 0.0, 30.0)

        def command_torque(self, torque_nm: float) -> MotorState:
            return MotorState(clock.t, 0.0, 0.1, torque_nm, 30.0)

        def disable(self) -> None:
            pass

    class Imu:
        def read(self) -> ElevationSample:
            t = clock.t
            return ElevationSample(t, 1.0 + 0.5 * math.sin(t), 0.5 * math.cos(t))

    class LoadCell:
        failure = None

        def read(self) -> TensionSample:
            return TensionSample(clock.t, 40.0)

    rows = []
    loop = ControlLoop(
        controller=build_controller(model=CompensationModel.from_friction(k=0.1), support=0.5,
                                    subject=Subject(height_m=1.70, mass_kg=63.0, sex="female")),
        motor=Motor(), elevation_sensor=Imu(), tension_sensor=LoadCell(), clock=clock,  # type: ignore[arg-type]
        config=LoopConfig(rate_hz=500.0, duration_s=cycles / 500.0), record=rows.append,
        reference_elevation=math.sin, recorder_failure=lambda: None,
    )
    start = time.process_time()  # CPU time: what other processes on a busy machine do not add to
    report = loop.run()
    elapsed = time.process_time() - start
    assert report.cycles >= cycles and len(rows) == report.cycles
    return elapsed / report.cycles


def run_in(source: Path, cycles: int) -> float:
    # The source tree goes first on sys.path, before the installed (editable) bowden.
    code = (f"import sys; sys.path[:0] = [{str(source / 'src')!r}, {str(ROOT / 'benchmarks')!r}]; "
            f"import loop_body; print(loop_body.measure({cycles}))")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=50_000)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--against", metavar="REV", help="also measure the loop of this git revision")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        sources = {"this tree": ROOT}
        if args.against:
            other = Path(scratch) / "other"
            subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(other), args.against],
                           check=True, capture_output=True)
            sources[args.against] = other
        try:
            times: dict[str, list[float]] = {name: [] for name in sources}
            for _ in range(args.repeats):  # interleaved, so a change in the machine's load hits both
                for name, source in sources.items():
                    times[name].append(run_in(source, args.cycles))
        finally:
            if args.against:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(other)],
                               check=False, capture_output=True)
    medians = {name: statistics.median(values) for name, values in times.items()}
    for name, value in medians.items():
        print(f"{name:>12}: {value * 1e6:6.2f} µs of CPU per cycle (median of {args.repeats} runs of "
              f"{args.cycles} cycles; the period at 500 Hz is 2000 µs)")
    if args.against:
        print(f"ratio this tree / {args.against}: {medians['this tree'] / medians[args.against]:.3f}")


if __name__ == "__main__":
    main()
