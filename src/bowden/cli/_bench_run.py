"""``bowden bench run``: open the bench (real or simulated), run the protocol, report.

Private to the CLI (leading underscore: the subcommand discovery skips it); :mod:`bowden.cli.bench`
registers the command. Exit codes as ``bowden run``'s: 0 the protocol is complete, 3 a watchdog
stopped the bench safely (the strokes recorded are kept; ``--resume`` continues), 1 nothing ran
(bad options, a device that does not answer), 130 interrupted.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path
from typing import Any

from bowden.cli._flag_errors import flag_errors
from bowden.cli._outputs import check_output_file
from bowden.errors import ParameterError
from bowden.hardware.backend import Backend
from bowden.model import CompensationModel
from bowden.protocol.bench import BenchProtocol, BenchStroke, LatencyChirp, StudyStrokes
from bowden.runtime.bench import BenchDevices, BenchRun, BenchRunConfig, BenchSafety
from bowden.runtime.bench_config import FitModels
from bowden.runtime.bench_recording import BenchRecordingWriter
from bowden.runtime.signals import stop_on_signals
from bowden.runtime.slack import SlackTakeUp

EXIT_FAULT = 3


def _say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


# The protocol's and the bench's fields that a flag sets in the field's own unit (flag_errors).
_BENCH_FLAGS = {
    "BenchProtocol.spool_speeds_rad_s": "--speeds",
    "BenchProtocol.loads_nm": "--loads",
    "BenchProtocol.repetitions": "--repetitions",
    "BenchProtocol gains": "--kp and --kd",
    "BenchSafety.max_tension_n": "--max-tension",
    "SlackTakeUp.pretension_n": "--pretension",
    "SlackTakeUp.pulley_radius_m": "--spool-radius",
}


def bench_protocol(args: argparse.Namespace) -> BenchProtocol:
    """The protocol of ``bowden bench simulate`` or ``run`` from its options (validated)."""
    _check_stroke_range(getattr(args, "low_deg", None), getattr(args, "high_deg", None))
    overrides: dict[str, object] = {}
    if args.speeds:
        overrides["spool_speeds_rad_s"] = tuple(args.speeds)
    if args.loads:
        overrides["loads_nm"] = tuple(args.loads)
    if args.repetitions is not None:
        overrides["repetitions"] = args.repetitions
    if getattr(args, "low_deg", None) is not None:
        overrides["low_rad"] = math.radians(args.low_deg)
    if getattr(args, "high_deg", None) is not None:
        overrides["high_rad"] = math.radians(args.high_deg)
    if getattr(args, "kp", None) is not None:
        overrides["position_gain_nm_rad"] = args.kp
    if getattr(args, "kd", None) is not None:
        overrides["velocity_gain_nms_rad"] = args.kd
    with flag_errors(_BENCH_FLAGS):
        return BenchProtocol(**overrides)  # type: ignore[arg-type]


def _check_stroke_range(low_deg: float | None, high_deg: float | None) -> None:
    """``--low-deg`` and ``--high-deg`` in degrees, as typed (the protocol checks them in radians)."""
    default = BenchProtocol()
    low = math.degrees(default.low_rad) if low_deg is None else low_deg
    high = math.degrees(default.high_rad) if high_deg is None else high_deg
    if not 0.0 < low < high < 180.0:  # NaN fails too
        raise ParameterError(f"--low-deg and --high-deg need 0 < low < high < 180 degrees, "
                             f"got {low:g} and {high:g}")


def bench_config(args: argparse.Namespace) -> BenchRunConfig:
    """The run's configuration from the command line (validated: bad numbers are one line)."""
    protocol = bench_protocol(args)
    _check_loads(protocol, args.mannequin_motor)
    with flag_errors(_BENCH_FLAGS):
        slack = SlackTakeUp(pretension_n=args.pretension, pulley_radius_m=args.spool_radius)
        safety = BenchSafety(max_tension_n=args.max_tension)
    if getattr(args, "backend", "can") == "sim":  # its devices share this host's CPUs
        safety = safety.on_shared_host()
    later = not getattr(args, "no_later_segments", True)
    return BenchRunConfig(protocol=protocol, spool_radius_m=args.spool_radius, slack=slack, safety=safety,
                          latency=latency_chirp(args) if later else None,
                          study=study_strokes(args) if later else None)


def _refuse_later_segment_flags(args: argparse.Namespace) -> None:
    """The later segments' flags with ``--no-later-segments`` (``bench run``): refused, not ignored."""
    given = [flag for flag, name in (("--chirp-s", "chirp_s"), ("--study-supports", "study_supports"),
                                     ("--study-speeds", "study_speeds"),
                                     ("--study-repetitions", "study_repetitions"))
             if getattr(args, name, None) is not None]
    if given:
        raise ParameterError(f"{', '.join(given)}: the later segments' settings, which --no-later-segments "
                             "leaves out")


def latency_chirp(args: argparse.Namespace) -> LatencyChirp:
    """The latency segment from ``--chirp-s`` (validated by :class:`LatencyChirp`, which names the flag)."""
    if args.chirp_s is None:
        return LatencyChirp()
    return LatencyChirp(duration_s=args.chirp_s)


def study_strokes(args: argparse.Namespace) -> StudyStrokes:
    """The study-like segment from ``--study-supports``, ``--study-speeds``, ``--study-repetitions``."""
    overrides: dict[str, object] = {}
    if args.study_supports:
        supports: list[float | str] = []
        for text in args.study_supports:
            try:
                value: float | str = text if text == "pretension" else float(text)
            except ValueError:
                raise ParameterError(f"--study-supports: {text!r} is neither 'pretension' nor a "
                                     "fraction") from None
            if isinstance(value, float) and not 0.0 < value <= 1.0:
                raise ParameterError(f"--study-supports: {text} is not a fraction in (0, 1]")
            supports.append(value)
        overrides["supports"] = tuple(supports)
    if args.study_speeds:
        overrides["speeds"] = tuple(args.study_speeds)
    if args.study_repetitions is not None:
        if not 2 <= args.study_repetitions <= 50:
            raise ParameterError(f"--study-repetitions must be in [2, 50], got {args.study_repetitions}")
        overrides["repetitions"] = args.study_repetitions
    return StudyStrokes(**overrides)  # type: ignore[arg-type]


def bench_model_source(args: argparse.Namespace) -> Callable[[Path, Path | None], CompensationModel]:
    """What gives the study-like segment its model: the identification of what this run recorded
    (its strokes, the IMU latency from its chirp), as ``bowden identify`` would with its defaults and
    ``--pulley-radius-mm`` of ``--spool-radius``; written beside the recording (``<stem>.model.json``)."""
    def identify(recording: Path, latency: Path | None) -> CompensationModel:
        from bowden.identify import TransmissionIdentifier
        from bowden.identify.latency import read_latency_segment
        from bowden.model.model_file import save_model

        options: dict[str, Any] = {"pulley_radius_m": args.spool_radius}
        if latency is not None:
            estimate = read_latency_segment(str(latency), flag="the bench's latency segment")
            options["imu_latency_s"] = estimate.latency_s
            _say(f"IMU latency identified from the chirp: {1e3 * estimate.latency_s:.1f} ms")
        identifier = TransmissionIdentifier(**options)
        identifier.fit(recording)
        model_path = Path(args.output).with_name(Path(args.output).stem + ".model.json")
        save_model(identifier.model_, model_path)
        _say(f"the study-like segment runs the controller on the model identified now ({model_path})")
        return identifier.model_

    return identify


def _check_loads(protocol: BenchProtocol, motor: str) -> None:
    """Refuse, before anything moves, a load the mannequin's motor cannot apply: its MIT torque field
    spans its peak torque (the AK80-9's 18 Nm: CubeMars AK80-9 KV100 specifications, peak torque
    18 N·m; ``bowden.hardware.ak60_codec.MOTOR_LIMITS``), and a command beyond it is clipped."""
    from bowden.hardware.ak60_codec import limits_for_motor

    peak_nm = limits_for_motor(motor).torque_nm
    over = [load for load in protocol.loads_nm if load > peak_nm]
    if over:
        raise ParameterError(f"--loads {' '.join(f'{load:g}' for load in over)} Nm: beyond the "
                             f"{peak_nm:g} Nm peak torque of the mannequin's motor ({motor}, "
                             "--mannequin-motor)")


def _open(args: argparse.Namespace) -> AbstractContextManager[Backend]:
    if args.mannequin_id == args.motor_id:
        raise ParameterError(f"--mannequin-id {args.mannequin_id} is the TDU's id (--motor-id): "
                             "each motor needs its own CAN id")
    if args.backend == "sim":
        from bowden.sim.backend import open_sim_bench

        # The simulated bench is built as the real one (TDU id 1, an AK80-9 on id 2); the options
        # name what the drivers expect, so a wrong id or model fails here as on the real bus.
        return open_sim_bench(announce=_say, mannequin_id=args.mannequin_id,
                              mannequin_motor=args.mannequin_motor,
                              mannequin_direction=args.mannequin_direction,
                              motor=args.motor, firmware=args.firmware)
    from bowden.cli._suit import CanSuitOptions, open_can_backend, require_hardware_extra
    from bowden.hardware.ak60 import AK60Config
    from bowden.hardware.ak60_codec import limits_for_motor

    options = CanSuitOptions.from_args(args)
    if options.i2c_bus is None:
        raise ParameterError("bowden bench run --backend can needs the load cell (--i2c-bus N): "
                             "identification fits torque against the measured tension")
    require_hardware_extra("bowden bench run", options)
    limits = limits_for_motor(args.mannequin_motor)
    mannequin = AK60Config(motor_id=args.mannequin_id, limits=limits, direction=args.mannequin_direction,
                           torque_limit_nm=limits.torque_nm)
    return open_can_backend(options, announce=_say, mannequin=mannequin)


@contextmanager
def _realtime() -> Iterator[str]:
    """The loop thread's real-time settings (as ``bowden run``'s), on the simulated bench too: its
    devices' process runs under ``SCHED_FIFO`` 40 on the same machine, and a loop of normal priority
    fell behind them (1.18 ms of work per 1 ms cycle on a slow two-core host, 0.48 ms with these
    settings, 2026-11-28)."""
    from bowden.runtime.realtime import RealtimeConfig, realtime

    with realtime(RealtimeConfig()) as report:
        yield report.describe()


@contextmanager
def _discard_if_unused(writer: BenchRecordingWriter) -> Iterator[None]:
    """A run that fails before any stroke (a device that does not open) leaves no empty recording
    behind, so the next attempt needs no --resume."""
    try:
        yield
    except BaseException:
        writer.discard_if_empty()
        raise


def run_bench_on_backend(args: argparse.Namespace) -> int:
    if args.no_later_segments:
        _refuse_later_segment_flags(args)
    config = bench_config(args)
    return run_bench_config(args, config, model_source=bench_model_source(args))


def run_bench_config(args: argparse.Namespace, config: BenchRunConfig, *,
                     model_source: Callable[[Path, Path | None], CompensationModel],
                     fit_models: FitModels | None = None, output_flag: str = "-o") -> int:
    """Open the bench of ``args``, run ``config``'s protocol into ``args.output``, report; the exit code.

    ``output_flag`` is the flag that named ``args.output`` (``bench validate``'s ``--bench-output``).
    """
    strokes = config.protocol.n_strokes if config.identification else 0
    total = config.n_units
    # The commands' shared check, before the bench opens: it names the flag, and a missing folder
    # as missing (the writer's own check said "is not a directory" of it).
    check_output_file(f"the bench recording ({output_flag})", Path(args.output), create_parents=False)
    opener = _open(args)  # checks the options; the devices open below
    with BenchRecordingWriter(args.output, config.protocol_fingerprint(), resume=args.resume) as writer, \
            _discard_if_unused(writer):
        done = writer.resume_point.strokes_done
        if done:
            _say(f"resuming {args.output}: {done} of {total} units recorded ({strokes} strokes, then the "
                 f"later segments' blocks), going on with unit {done + 1}")
        live = sys.stderr.isatty()

        def progress(stroke: BenchStroke, strokes: int) -> None:
            line = (f"stroke {stroke.index + 1} of {strokes}: {stroke.spool_velocity_rad_s:+g} rad/s, "
                    f"load {stroke.load_nm:g} Nm, repetition {stroke.repetition + 1}")
            print(("\r" + line + "   ") if live else line, end="" if live else "\n", file=sys.stderr,
                  flush=True)

        with opener as backend:
            if backend.load_cell is None or backend.mannequin is None:
                raise ParameterError("the bench needs a load cell and the mannequin's motor")
            _say(f"bench: {backend.describe}")
            tdu: Any = backend.motor  # an AK60Motor on the bench (command_mit; checked by the run's use)
            devices = BenchDevices(tdu=tdu, mannequin=backend.mannequin, imu=backend.imu,
                                   load_cell=backend.load_cell, clock=backend.clock)
            bench = BenchRun(devices, config, writer, progress=progress, model_source=model_source,
                             announce=_say, fit_models=fit_models)
            # SIGINT and SIGTERM (whatever the process inherited: a script's background job ignores
            # SIGINT) ask for the safe stop, taken at the next cycle's start: an exception raised
            # wherever the signal lands could leave a driver's lock held or cut the safe stop short.
            with _realtime() as settings, stop_on_signals(bench.request_stop):
                if settings:
                    _say(f"real-time settings: {settings}")
                report = bench.run()
        if live:
            print(file=sys.stderr)
        for error in report.exit_errors:
            _say(f"warning: {error}")
        if report.data_gaps:
            _say(f"warning: the load cell's reader was starved {report.data_gaps} times (a busy host); "
                 "the strokes recorded then were run again")
        if report.complete:
            path = writer.finish()
            _say_written(config, writer, path)
            return 0
    recorded = f"{min(report.strokes_done, strokes)} of {strokes} strokes are recorded in {args.output}"
    if total > strokes:
        blocks = max(report.strokes_done - strokes, 0)
        recorded += f" (the later segments: {blocks} of {total - strokes} blocks)"
    if report.fault == "interrupted":
        _say(f"bowden: interrupted; both motors are out of motor mode. {recorded}; add --resume to go on")
        return 130
    _say(f"bowden: bench stopped safely: {report.fault}. {recorded}; fix the cause and add --resume to go on")
    return EXIT_FAULT


def _say_written(config: BenchRunConfig, writer: BenchRecordingWriter, path: Path) -> None:
    """What the run wrote and how ``bowden identify`` reads it."""
    if config.identification:
        print(f"wrote {config.protocol.n_strokes} strokes to {path}")
    latency, study = writer.segment_path("latency"), writer.segment_path("study")
    if config.latency is not None:
        print(f"wrote the latency chirp to {latency}")
    if config.study is not None or config.fit is not None:
        fit = f" (the first {len(config.fit.blocks())} the fit's)" if config.fit is not None else ""
        print(f"wrote {len(config.study_blocks())} study-like blocks{fit} to {study}")
    if not config.identification:  # bench validate: it judges what it ran itself
        return
    command = f"bowden identify {path} -o model.json"
    if config.latency is not None:
        command += f" --latency-recording {latency}"
    if config.study is not None:
        command += f" --study-recording {study}"
    print(f"identify them with `{command}`")
