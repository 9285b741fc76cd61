"""``bowden bench simulate -o bench.csv``: run the paper's identification protocol on the simulated bench.

The mannequin bench of :mod:`bowden.sim.bench` (spool speeds ±0.5–6 rad/s, loads 0.5–4 Nm, five
repetitions, 20°–110°) writes a bench recording in the contract format; the file's extension picks
the format (``.csv`` or ``.parquet``). ``bowden identify bench.csv -o model.json`` then fits it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bowden.errors import OutputFileError, ParameterError

_FORMATS = {".csv": "csv", ".parquet": "parquet"}


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser("bench", help="the mannequin bench (simulated)")
    actions = parser.add_subparsers(title="actions", metavar="ACTION")
    simulate = actions.add_parser(
        "simulate",
        help="run the identification protocol on the simulated mannequin bench",
        description="Write a simulated bench recording (time_s, motor_torque_nm, motor_velocity_rad_s, "
        "tension_n, elevation_rad, trial) for `bowden identify`.",
    )
    simulate.add_argument(
        "-o", "--output", type=Path, required=True, help="recording to write (.csv or .parquet)"
    )
    simulate.add_argument("--seed", type=int, default=0, help="seed of the sensor noise (default 0)")
    simulate.add_argument(
        "--speeds", type=float, nargs="+", metavar="RAD_S",
        help="spool speeds, rad/s (default: 0.5 1 2 3 4 5 6)",
    )
    simulate.add_argument(
        "--loads", type=float, nargs="+", metavar="NM", help="mannequin loads, Nm (default: 0.5 1 2 3 4)"
    )
    simulate.add_argument("--repetitions", type=int, help="repetitions of each speed and load (default 5)")
    simulate.add_argument("--quiet", action="store_true", help="no progress output")
    simulate.set_defaults(handler=run_simulate)
    parser.set_defaults(handler=lambda args: _usage(parser))


def _usage(parser: argparse.ArgumentParser) -> int:
    parser.print_help()
    return 2


def run_simulate(args: argparse.Namespace) -> int:
    from bowden.sim.bench import BenchProtocol, run_bench

    output: Path = args.output
    fmt = _FORMATS.get(output.suffix.lower())
    if fmt is None:
        raise ParameterError(f"cannot tell the format of {output}: use a .csv or .parquet extension")
    if not output.absolute().parent.is_dir():  # before a minute of simulation, not after it
        raise OutputFileError(f"cannot write the bench recording to {output}: "
                              f"{output.absolute().parent} is not a directory")
    overrides: dict[str, object] = {}
    if args.speeds:
        overrides["spool_speeds_rad_s"] = tuple(args.speeds)
    if args.loads:
        overrides["loads_nm"] = tuple(args.loads)
    if args.repetitions is not None:
        overrides["repetitions"] = args.repetitions
    protocol = BenchProtocol(**overrides)  # type: ignore[arg-type]

    # A line redrawn in place on a terminal; in a log (not a terminal) only every tenth of the way.
    live = sys.stderr.isatty()
    printed_tenths = 0

    def progress(done: int, total: int) -> None:
        nonlocal printed_tenths
        if live:
            print(f"\rbench: {done}/{total} strokes", end="", file=sys.stderr, flush=True)
        elif done * 10 // total > printed_tenths:
            printed_tenths = done * 10 // total
            print(f"bench: {done}/{total} strokes", file=sys.stderr, flush=True)

    frame = run_bench(protocol=protocol, seed=args.seed, progress=False if args.quiet else progress)
    if not args.quiet and live:
        print(file=sys.stderr)
    try:
        if fmt == "csv":
            frame.to_csv(output, index=False)
        else:
            frame.to_parquet(output, index=False)
    except OSError as error:
        reason = error.strerror or error
        raise OutputFileError(f"cannot write the bench recording to {output}: {reason}") from None
    duration = float(frame["time_s"].iloc[-1])
    print(f"wrote {len(frame)} samples ({duration:.0f} s simulated, {protocol.n_strokes} strokes) "
          f"to {output}")
    return 0
