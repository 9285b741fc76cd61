"""``bowden identify BENCH... -o model.json [--figure fig.png]``: bench recordings to a compensation model.

Writes model.json version 2: the paper's lines and, identified from the same recording, the dynamic
compensation (:mod:`bowden.identify.dynamic`; ``--paper-only`` leaves it out).

Reads one or several bench recordings (CSV or Parquet), runs the paper's identification (see
:mod:`bowden.identify`), writes the versioned ``model.json`` with provenance, prints the summary
(lines, both R², n, implied k, single-bend check, warnings) and optionally draws the regression
figure. Selection thresholds are given in the paper's units (degrees) on the command line.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bowden.cli._flag_errors import flag_errors
from bowden.cli._outputs import check_output_file, refuse_overwriting_inputs
from bowden.errors import FitError, OutputFileError, ParameterError, RecordingError
from bowden.hardware.motors import AK_MOTORS, DEFAULT_MOTOR
from bowden.identify.settings import DEFAULT_IMU_LATENCY_S, LOWERING, RAISING, PreprocessSettings
from bowden.model.compensation import CompensationModel
from bowden.model.model_file import save_model
from bowden.validation import check_number

if TYPE_CHECKING:  # imported by run(): bowden identify --help needs no fitting stack
    from bowden.identify.estimator import TransmissionIdentifier

_DEFAULTS = PreprocessSettings()


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "identify",
        help="fit the raising/lowering compensation lines from bench recordings",
        description=(
            "Identify the Bowden transmission from bench recordings (columns time_s, motor_torque_nm, "
            "motor_velocity_rad_s, tension_n, elevation_rad, optional trial) and write model.json."
        ),
    )
    parser.add_argument(
        "bench", nargs="+", type=Path, metavar="BENCH", help="bench recording(s), .csv or .parquet"
    )
    parser.add_argument("-o", "--output", type=Path, required=True, help="model file to write (model.json)")
    parser.add_argument("--motor", choices=tuple(AK_MOTORS), default=DEFAULT_MOTOR,
                        help="the TDU's AK-series model the bench data were recorded with, recorded in the "
                        f"model (default {DEFAULT_MOTOR}; bowden run refuses the model on another --motor)")
    parser.add_argument("--figure", type=Path, help="also draw the regression figure (.png, .pdf, .svg)")
    parser.add_argument(
        "--pulley-radius-mm", type=float, default=35.0, help="spool radius in mm (default 35, the paper's)"
    )
    parser.add_argument("--cutoff-hz", type=float, default=_DEFAULTS.cutoff_hz, help="low-pass cutoff (5 Hz)")
    parser.add_argument(
        "--min-speed-deg-s", type=float, default=15.0, help="keep |spool speed| above this (15 °/s)"
    )
    parser.add_argument(
        "--max-acceleration-deg-s2",
        type=float,
        default=15.0,
        help="keep |spool acceleration| below this (15 °/s²)",
    )
    parser.add_argument(
        "--min-elevation-deg", type=float, default=20.0, help="keep elevation above this (20°)"
    )
    parser.add_argument(
        "--max-elevation-deg", type=float, default=90.0, help="keep elevation below this (90°)"
    )
    parser.add_argument(
        "--min-samples",
        type=int,
        default=50,
        help="fewer steady-state samples in a direction is an error (50)",
    )
    parser.add_argument(
        "--ignore-extra-columns", action="store_true", help="ignore columns outside the bench contract"
    )
    parser.add_argument(
        "--imu-latency-ms",
        type=float,
        # None when not given: --paper-only and --latency-recording refuse it given (it would be ignored).
        default=None,
        help="age of the suit's IMU samples on arrival, for the dynamic compensation's estimator "
        f"(default {1e3 * DEFAULT_IMU_LATENCY_S:g})",
    )
    parser.add_argument(
        "--study-recording",
        type=Path,
        help="the bench's study-like segment (`bowden bench run`'s <stem>.study.csv): recommend the "
        "dynamic compensation per (support, speed) cell from it (docs/identification.md)",
    )
    parser.add_argument(
        "--latency-recording",
        type=Path,
        help="the bench's latency segment (time_s, elevation_rad, mannequin_elevation_rad): identify the "
        "IMU's latency from it instead of assuming --imu-latency-ms (docs/identification.md)",
    )
    parser.add_argument(
        "--paper-only", action="store_true", help="write the paper's lines only (model.json without dynamic)"
    )
    parser.add_argument(
        "--friction-figure", type=Path, help="also draw the dynamic friction against cable velocity"
    )
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    # The fitting (statsmodels, SciPy's signal processing, pandas) and the figures (matplotlib) are
    # imported here, not at the top: bowden --help and bowden identify --help read the settings alone.
    from bowden.identify.dynamic import format_dynamic
    from bowden.identify.estimator import TransmissionIdentifier

    _check_outputs(args.output, args.figure, args.bench)
    if args.friction_figure is not None:
        _check_outputs(args.output, args.friction_figure, args.bench)
        if args.paper_only:
            raise ParameterError("--friction-figure draws the dynamic model, which --paper-only leaves out")
    _refuse_ignored_flags(args)
    _check_degree_and_mm_flags(args)  # every flag before the latency segment is read
    imu_latency_s = DEFAULT_IMU_LATENCY_S if args.imu_latency_ms is None else args.imu_latency_ms / 1000.0
    if args.latency_recording is not None:
        from bowden.identify.latency import read_latency_segment

        latency = read_latency_segment(str(args.latency_recording))
        imu_latency_s = latency.latency_s
        print(f"IMU latency identified from {args.latency_recording}: {1e3 * latency.latency_s:.1f} ms "
              f"(residual {math.degrees(latency.residual_rms_rad):.2f}°)")
    # The settings check the flags in their own units too; their refusals name the flags.
    with flag_errors({"cutoff_hz": "--cutoff-hz", "min_samples_per_direction": "--min-samples"}):
        settings = PreprocessSettings(
            cutoff_hz=args.cutoff_hz,
            min_speed_rad_s=math.radians(args.min_speed_deg_s),
            max_abs_acceleration_rad_s2=math.radians(args.max_acceleration_deg_s2),
            min_elevation_rad=math.radians(args.min_elevation_deg),
            max_elevation_rad=math.radians(args.max_elevation_deg),
        )
        identifier = TransmissionIdentifier(
            preprocessing=settings,
            pulley_radius_m=args.pulley_radius_mm / 1000.0,
            min_samples_per_direction=args.min_samples,
            dynamic=not args.paper_only,
            imu_latency_s=imu_latency_s,
        )
    # The study-like recording is read and judged before the fit: a file it refuses costs no fit.
    study_results = None if args.study_recording is None else read_study_results(args.study_recording)
    _fit(identifier, args.bench, ignore_extra_columns=args.ignore_extra_columns)
    model = identifier.model_
    if study_results is not None:
        model = recommend_from_study_results(model, study_results)
    save_model(model, args.output, motor=args.motor)
    print(identifier.summary_.format())
    dynamic = model.dynamic
    if dynamic is not None:
        print(format_dynamic(dynamic))
    elif identifier.dynamic_error_ is not None:
        print(f"No dynamic compensation: {identifier.dynamic_error_}; the model holds the paper's lines only")
    print(f"Model written to {args.output}")
    if args.figure is not None:
        from bowden.identify.figure import save_identification_figure

        fits = {RAISING: identifier.raising_fit_, LOWERING: identifier.lowering_fit_}
        save_identification_figure(identifier.selection_, fits, args.figure)
        print(f"Figure written to {args.figure}")
    if args.friction_figure is not None:
        if dynamic is None:
            raise FitError(f"no friction figure: {identifier.dynamic_error_}")
        from bowden.identify.friction_figure import save_friction_figure

        radius = identifier.model_.pulley_radius_m
        save_friction_figure(identifier.selection_, dynamic, radius, args.friction_figure)
        print(f"Friction figure written to {args.friction_figure}")
    if identifier.summary_.warnings:
        print(f"bowden identify: {len(identifier.summary_.warnings)} warning(s), see above", file=sys.stderr)
    return 0


def _fit(identifier: TransmissionIdentifier, benches: list[Path], *, ignore_extra_columns: bool) -> None:
    """Read the bench recordings and fit; a file of other columns is refused in one line (the
    library's error lists every problem, one per line, for its callers)."""
    from bowden.identify.recording import read_bench_recording
    from bowden.identify.validation import BenchColumnsError

    try:
        recording = read_bench_recording(
            benches, limits=identifier.limits, allow_extra_columns=ignore_extra_columns
        )
    except BenchColumnsError as error:
        raise RecordingError(error.one_line("--ignore-extra-columns")) from None
    identifier.fit(recording)


def _refuse_ignored_flags(args: argparse.Namespace) -> None:
    """Refuse the flags nothing would read: the IMU latency's and the study-like recording's serve
    only the dynamic compensation (the paper's lines take no latency, and with them alone a study
    recording recommends nothing), and ``--latency-recording`` replaces ``--imu-latency-ms``.
    Ignored, either would leave the model other than the user asked."""
    if args.imu_latency_ms is not None and not 0.0 <= args.imu_latency_ms <= 200.0:  # NaN fails too
        raise ParameterError(f"--imu-latency-ms must be in [0, 200] ms, got {args.imu_latency_ms:g}")
    if args.paper_only and args.study_recording is not None:
        raise ParameterError("--study-recording chooses where the dynamic compensation runs, which "
                             "--paper-only leaves out")
    if args.paper_only:
        given = [flag for flag, value in (("--imu-latency-ms", args.imu_latency_ms),
                                          ("--latency-recording", args.latency_recording))
                 if value is not None]
        if given:
            raise ParameterError(f"{', '.join(given)}: the dynamic compensation's IMU latency, which "
                                 "--paper-only leaves out (the paper's lines take none)")
    if args.imu_latency_ms is not None and args.latency_recording is not None:
        raise ParameterError("--imu-latency-ms and --latency-recording both set the IMU latency: "
                             "--latency-recording identifies it from the segment; drop one")


def _check_degree_and_mm_flags(args: argparse.Namespace) -> None:
    """The flags given in another unit than their settings' fields, checked as typed (degrees, mm)."""
    check_number(args.min_speed_deg_s, "--min-speed-deg-s", 0.0)
    check_number(args.max_acceleration_deg_s2, "--max-acceleration-deg-s2", 0.0, low_open=True)
    check_number(args.min_elevation_deg, "--min-elevation-deg", -90.0, 180.0)
    check_number(args.max_elevation_deg, "--max-elevation-deg", -90.0, 180.0)
    if not args.min_elevation_deg < args.max_elevation_deg:
        raise ParameterError(f"--min-elevation-deg ({args.min_elevation_deg:g}) must be below "
                             f"--max-elevation-deg ({args.max_elevation_deg:g})")
    # TransmissionIdentifier's bound, (0, 0.5) m, in the flag's millimetres.
    if not 0.0 < args.pulley_radius_mm < 500.0:  # NaN fails too
        raise ParameterError(f"--pulley-radius-mm must be in (0, 500) mm, got {args.pulley_radius_mm:g}")


def read_study_results(path: Path) -> dict[tuple[str, str], dict[str, Any]]:
    """The recorded study-like strokes judged per cell (``--study-recording``)."""
    from bowden.identify.study_recording import read_study_recording

    return read_study_recording(path)


def recommend_from_study_results(model: CompensationModel,
                                 results: dict[tuple[str, str], dict[str, Any]]) -> CompensationModel:
    """``model`` with the recommendation the recorded study-like strokes give (the per-cell table
    printed); unchanged, and said so, when it has no dynamic compensation."""
    from bowden.identify.study_recommendation import recommendation

    print_study_results(results)
    if model.dynamic is None:
        print("the model has no dynamic compensation: the study-like strokes recommend nothing")
        return model
    choice = recommendation(results)
    print(f"recommended: {choice.why}")
    return choice.apply(model)


def print_study_results(results: dict[tuple[str, str], dict[str, Any]]) -> None:
    """The study-like segment's table: support, speed, compensation, tension RMSE, onset peak."""
    print("support     speed  compensation  tension RMSE (N)  lowering-onset peak (%)")
    for (support, speed), by_name in results.items():
        for name, result in by_name.items():
            print(f"{support:10s}  {speed:5s}  {name:12s}  {result.tension_rmse_n:16.2f}  "
                  f"{result.onset_peak_pct:23.1f}")


def _check_outputs(model: Path, figure: Path | None, benches: list[Path]) -> None:
    """Refuse outputs that name an input or cannot be written, before the fit (no half result)."""
    inputs = {bench: "a bench recording to identify from" for bench in benches}
    refuse_overwriting_inputs("-o", model, inputs)
    check_output_file("the model (-o)", model, create_parents=False)
    if figure is None:
        return
    refuse_overwriting_inputs("--figure", figure, {**inputs, model: "the model file (-o)"})
    check_output_file("the figure (--figure)", figure, create_parents=False)
    from matplotlib.backend_bases import FigureCanvasBase

    kinds = FigureCanvasBase.get_supported_filetypes()
    if figure.suffix and figure.suffix[1:].lower() not in kinds:
        raise OutputFileError(
            f"cannot write the figure (--figure) to {figure}: matplotlib does not write "
            f"{figure.suffix!r} files (use one of {', '.join('.' + kind for kind in sorted(kinds))})"
        )
