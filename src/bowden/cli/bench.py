"""``bowden bench``: the paper's identification protocol on the mannequin bench.

* ``bowden bench simulate -o bench.csv`` — the fast batch path: the simulated bench of
  :mod:`bowden.sim.bench` integrated directly (spool speeds ±0.5–6 rad/s, loads 0.5–4 Nm, five
  repetitions, 20°–110°);
* ``bowden bench run --backend can|sim -o bench.csv`` — the protocol driven in real time over the
  devices' wires (:mod:`bowden.runtime.bench`): the real bench (TDU and mannequin motor on CAN,
  NGIMU, ADS1115) or the simulated one behind its wire peers. Crash-safe and resumable (``--resume``).

Both write a bench recording in the contract format (the extension picks ``.csv`` or ``.parquet``);
``bowden identify bench.csv -o model.json`` then fits it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from bowden.errors import OutputFileError, ParameterError

_FORMATS = {".csv": "csv", ".parquet": "parquet"}


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser("bench", help="the mannequin bench: run the identification protocol")
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
    simulate.add_argument("--low-deg", type=float, help="low end of the strokes, degrees (default 20)")
    simulate.add_argument("--high-deg", type=float, help="high end of the strokes, degrees (default 110)")
    simulate.add_argument("--quiet", action="store_true", help="no progress output")
    simulate.add_argument(
        "--latency-out", type=Path,
        help="also write the latency segment (time_s, elevation_rad, mannequin_elevation_rad) for "
        "`bowden identify --latency-recording`",
    )
    simulate.set_defaults(handler=run_simulate)
    _register_run(actions)
    validate = actions.add_parser(
        "validate",
        help="run the study-like segment with both compensations and recommend one",
        description="The mannequin moves the arm along the study's minimum-jerk cycle (20°-100°-20°, "
        "V1-V3) while the controller runs each compensation; prints tension RMSE and lowering-onset "
        "peak per speed against the load cell, and which compensation the model should recommend.",
    )
    validate.add_argument("model", type=Path, help="the model.json to validate")
    validate.add_argument("--backend", choices=("sim", "can", "sim-wire"), default="sim",
                          help="sim: the batch simulated bench (default); can: the real bench over its "
                          "wires, in real time; sim-wire: the simulated bench over its wire peers, in real "
                          "time (as `bench run --backend sim`)")
    validate.add_argument("--recording", type=Path,
                          help="judge this recorded study-like segment (`bench run`'s <stem>.study.csv) "
                          "instead of running one")
    validate.add_argument("--bench-output", type=Path,
                          help="--backend can/sim-wire: where the run is recorded (default: "
                          "<MODEL stem>.validate.csv; the study-like strokes in <stem>.study.csv)")
    validate.add_argument("--resume", action="store_true", help="continue an interrupted --bench-output")
    validate.add_argument("--study-speeds", nargs="+", choices=("V1", "V2", "V3"),
                          help="--backend can/sim-wire: speeds (default: V1 V2 V3)")
    validate.add_argument("--study-repetitions", type=int,
                          help="--backend can/sim-wire: cycles per support, speed and compensation "
                          "(default 7)")
    _add_bench_devices(validate)
    validate.add_argument("--support", type=float,
                          help="only this support fraction (default: the study's pretension, 0.25 and 0.5)")
    validate.add_argument("--seed", type=int, default=0, help="seed of the sensor noise (default 0)")
    validate.add_argument("--fit", action="store_true",
                          help="first refit the dynamic compensation on one run of the strokes (at "
                          "--support, default 0.5: the paper's lines and 12 candidates per speed, 4 cycles "
                          "each), then validate on a second run held out of the fit; with --recording, "
                          "refit from a recorded fit (its candidate blocks)")
    validate.add_argument("-o", "--output", type=Path,
                          help="write the model with its recommendation here (may be MODEL itself)")
    validate.set_defaults(handler=run_validate)
    parser.set_defaults(handler=lambda args: _usage(parser))


def _usage(parser: argparse.ArgumentParser) -> int:
    parser.print_help()
    return 2


def _register_run(actions: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    run = actions.add_parser(
        "run",
        help="run the identification protocol in real time on a bench (real or simulated)",
        description="Drive the paper's identification protocol on a mannequin bench: the TDU in MIT-mode "
        "velocity tracking, the mannequin's motor in torque, strokes bounded by the IMU, every fault a "
        "safe stop. Strokes are written as they complete; --resume continues an interrupted recording.",
    )
    run.add_argument("-o", "--output", type=Path, required=True, help="recording to write (.csv or .parquet)")
    run.add_argument("--backend", choices=("can", "sim"), default="can",
                     help="can: the real bench; sim: the simulated bench over its wire peers (default can)")
    run.add_argument("--resume", action="store_true", help="continue an interrupted recording")
    run.add_argument("--speeds", type=float, nargs="+", metavar="RAD_S",
                     help="spool speeds, rad/s (default: 0.5 1 2 3 4 5 6)")
    run.add_argument("--loads", type=float, nargs="+", metavar="NM",
                     help="mannequin loads, Nm (default: 0.5 1 2 3 4)")
    run.add_argument("--repetitions", type=int, help="repetitions of each speed and load (default 5)")
    run.add_argument("--low-deg", type=float, help="low end of the strokes, degrees (default 20)")
    run.add_argument("--high-deg", type=float, help="high end of the strokes, degrees (default 110)")
    run.add_argument("--kp", type=float, help="TDU position gain, Nm/rad (default 30)")
    run.add_argument("--kd", type=float, help="TDU velocity gain, Nm·s/rad (default 0.6)")
    later = run.add_argument_group("the later segments (docs/identification.md, \"The protocol, exactly\")")
    later.add_argument("--no-later-segments", action="store_true",
                       help="run the identification strokes only (no latency chirp, no study-like strokes)")
    later.add_argument("--chirp-s", type=float, help="duration of the latency chirp, s (default 12)")
    later.add_argument("--study-supports", nargs="+", metavar="SUPPORT",
                       help="supports of the study-like strokes: pretension and/or fractions "
                       "(default: pretension 0.25 0.5)")
    later.add_argument("--study-speeds", nargs="+", choices=("V1", "V2", "V3"),
                       help="speeds of the study-like strokes (default: V1 V2 V3)")
    later.add_argument("--study-repetitions", type=int,
                       help="cycles per support, speed and compensation (default 7; the first is not judged)")
    _add_bench_devices(run)
    run.set_defaults(handler=run_bench_command)


def _add_bench_devices(parser: argparse.ArgumentParser) -> None:
    """The options of a bench's devices (``bench run``, and ``bench validate`` on a bench)."""
    from bowden.cli._suit import add_can_arguments

    parser.add_argument("--max-tension", type=float, default=250.0, help="tension limit, N (default 250)")
    parser.add_argument("--pretension", type=float, default=5.0,
                        help="tension at which the slack counts as taken up, N (default 5)")
    parser.add_argument("--spool-radius", type=float, default=0.035,
                        help="TDU pulley radius, m (default 0.035)")
    mannequin = parser.add_argument_group("mannequin motor (--backend can)")
    mannequin.add_argument("--mannequin-id", type=int, default=2, help="its CAN id (default 2)")
    mannequin.add_argument("--mannequin-motor", default="AK80-9",
                           help="its model, for the MIT field ranges (default AK80-9)")
    mannequin.add_argument("--mannequin-direction", type=int, choices=(1, -1), default=1,
                           help="+1 if its positive torque pulls the arm down (default 1)")
    add_can_arguments(parser)


def run_bench_command(args: argparse.Namespace) -> int:
    from bowden.cli._bench_run import run_bench_on_backend

    return run_bench_on_backend(args)


def run_validate(args: argparse.Namespace) -> int:
    from bowden.cli._outputs import check_output_file
    from bowden.identify.study_fit import STUDY_SUPPORTS
    from bowden.model.model_file import load_model
    from bowden.sim.parameters import check_seed

    check_seed(args.seed, "--seed")
    supports: tuple[float | str, ...] = STUDY_SUPPORTS
    if args.support is not None:
        if not 0.0 < args.support <= 1.0:
            raise ParameterError(f"--support must be in (0, 1], got {args.support:g}")
        supports = (args.support,)
    _refuse_unused_run_flags(args)
    model = load_model(args.model)
    if args.fit and model.dynamic is None:  # on every backend (the batch fit returned it unchanged)
        raise ParameterError(f"--fit: {args.model} has no dynamic compensation to refit")
    if args.output is not None:  # before the strokes run, not after
        if model.dynamic is None:
            raise ParameterError(f"-o: {args.model} has no dynamic compensation to recommend or not")
        check_output_file("the model (-o)", args.output, create_parents=False)
    if args.recording is not None or args.backend != "sim":
        return _validate_recorded(args, model, supports)
    return _validate_simulated(args, model, supports)


def _refuse_unused_run_flags(args: argparse.Namespace) -> None:
    """The flags of a run over the wires, refused where none runs (they would be silently ignored)."""
    given = [flag for flag, value in (("--bench-output", args.bench_output), ("--resume", args.resume),
                                      ("--study-speeds", args.study_speeds),
                                      ("--study-repetitions", args.study_repetitions))
             if value is not None and value is not False]
    if not given:
        return
    if args.recording is not None:
        raise ParameterError(f"{', '.join(given)}: --recording judges a recorded segment, nothing is run")
    if args.backend == "sim":
        raise ParameterError(f"{', '.join(given)}: for a run over the wires (--backend can or sim-wire); "
                             "the batch simulated bench (--backend sim) takes --support and --seed")


def _validate_simulated(args: argparse.Namespace, model: Any, supports: tuple[float | str, ...]) -> int:
    """``bench validate --backend sim``: the study-like segment on the batch simulated bench (with
    ``--fit`` the batch fit first, validated on other strokes)."""
    from bowden.sim.bench_study import fit_on_study_segment, validate_compensations
    from bowden.sim.parameters import SuitParameters

    suit = SuitParameters()
    seed = args.seed
    if args.fit:
        fit_support = 0.5 if args.support is None else args.support
        model = fit_on_study_segment(model, suit, seed=seed, support=fit_support)
        seed += 1  # validated on strokes held out of the fit
    results = validate_compensations(model, suit, seed=seed, supports=supports)
    return _report_validation(args, model, results)


def _validate_recorded(args: argparse.Namespace, model: Any, supports: tuple[float | str, ...]) -> int:
    """``bench validate`` on a recorded study-like segment: the one given (``--recording``), or one
    run now on a bench over its wires (``--backend can`` or ``sim-wire``) with both compensations;
    with ``--fit`` the fit's blocks first, and the validation on the candidate they chose."""
    from bowden.cli._bench_validate import check_recorded_model, default_fit, print_fit, run_study_on_bench
    from bowden.identify.study_recording import read_study_recording

    path, flag, unchecked = args.recording, "--recording", None
    if path is not None:
        unchecked = check_recorded_model(model, args.model, path)
    else:
        ran = run_study_on_bench(args, model, supports, fit=default_fit(args) if args.fit else None)
        if isinstance(ran, int):
            return ran
        path, flag = ran, "--bench-output"
    results = read_study_recording(path, flag=flag, after_fit=args.fit)
    if args.fit:
        model = print_fit(model, path, flag)
    if unchecked is not None:  # once the recording was judged: a refused one gets one error line alone
        print(unchecked, file=sys.stderr)
    return _report_validation(args, model, results)


def _report_validation(args: argparse.Namespace, model: Any, results: dict[Any, Any]) -> int:
    from bowden.cli.identify import print_study_results
    from bowden.identify.study_recommendation import recommendation
    from bowden.model.model_file import save_model

    print_study_results(results)
    choice = recommendation(results)
    print(f"recommended: {choice.why}")
    if args.output is not None:
        if model.dynamic is None:
            raise ParameterError("-o: the model has no dynamic compensation to recommend or not")
        save_model(choice.apply(model), args.output)
        print(f"Model written to {args.output}")
    return 0


def run_simulate(args: argparse.Namespace) -> int:
    from bowden.cli._bench_run import bench_protocol
    from bowden.cli._outputs import check_output_file, refuse_overwriting_inputs
    from bowden.sim.bench import run_bench
    from bowden.sim.parameters import check_seed

    output: Path = args.output
    fmt = _FORMATS.get(output.suffix.lower())
    if fmt is None:
        raise ParameterError(f"cannot tell the format of {output}: use a .csv or .parquet extension")
    check_seed(args.seed, "--seed")
    # Every output is checked before a minute of simulation, not after it.
    check_output_file("the bench recording (-o)", output.absolute(), create_parents=False)
    if args.latency_out is not None:
        refuse_overwriting_inputs("--latency-out", args.latency_out, {output: "the -o recording"})
        check_output_file("the latency segment (--latency-out)", args.latency_out.absolute(),
                          create_parents=False)
    protocol = bench_protocol(args)

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
    if args.latency_out is not None:
        from bowden.sim.bench_latency import run_latency_segment

        segment = run_latency_segment(seed=args.seed)
        try:
            segment.to_csv(args.latency_out, index=False)
        except OSError as error:
            raise OutputFileError(f"cannot write the latency segment to {args.latency_out}: "
                                  f"{error.strerror or error}") from None
        print(f"wrote the latency segment ({len(segment)} samples) to {args.latency_out}")
    duration = float(frame["time_s"].iloc[-1])
    print(f"wrote {len(frame)} samples ({duration:.0f} s simulated, {protocol.n_strokes} strokes) "
          f"to {output}")
    return 0
