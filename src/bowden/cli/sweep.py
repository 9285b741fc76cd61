"""``bowden sweep``: controller and suit parameters × virtual cohorts on Dask, scored by tracking error."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bowden.cli._flag_errors import flag_errors
from bowden.errors import ParameterError
from bowden.sweep import axes as ax
from bowden.sweep.presets import PRESETS, preset
from bowden.sweep.spec import SweepSpec, parse_support, parse_values

if TYPE_CHECKING:
    from rich.console import Console

# bowden --help marks the command, and running it is one line, while this extra is missing.
EXTRA = ("cluster", ("dask", "distributed"))


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "sweep",
        help="sweep controller and suit parameters over virtual cohorts on Dask (results in Parquet)",
        description=(
            "Simulate the study protocol at every point of a grid of controller (blend velocities) and "
            "suit parameters (sheath friction, torque constant, ...), for virtual cohorts, on a Dask "
            "cluster: a local one by default, or --scheduler ADDRESS. Each point is scored by the study's "
            "tracking errors; rows go to OUT/results.parquet, one summary row per configuration to "
            "OUT/points.parquet. A re-run with the same spec and --out resumes. "
            f"Presets: {', '.join(PRESETS)}."
        ),
    )
    parser.add_argument("preset", nargs="?", help=f"a named sweep ({', '.join(PRESETS)})")
    parser.add_argument("--spec", type=Path, metavar="FILE", help="a TOML sweep spec (see docs/sweep.md)")
    parser.add_argument(
        "--axis",
        action="append",
        default=[],
        metavar="NAME=V1,V2,...",
        help="sweep an axis over these values (repeatable; replaces the preset's or file's values)",
    )
    parser.add_argument("--participants", type=int, help="virtual participants per cohort")
    parser.add_argument("--seeds", metavar="S1,S2,...", help="one cohort per seed (default 0)")
    parser.add_argument("--repetitions", type=int, help="cycles per trial (first dropped; paper 10)")
    parser.add_argument("--support", metavar="LEVELS", help="support conditions, e.g. pretension,0.25,0.5")
    parser.add_argument("--speeds", metavar="V1,V2,V3", help="movement speeds")
    parser.add_argument(
        "--identification", choices=("per-suit", "nominal"), help="identify each suit, or the default one"
    )
    parser.add_argument("--bench", choices=("paper", "quick"), help="identification protocol")
    parser.add_argument("--out", type=Path, help="output directory (default bowden-sweep-<name>)")
    parser.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler (tcp://host:8786)")
    parser.add_argument("--workers", type=int, help="worker processes of the local cluster (default: cores)")
    parser.add_argument("--force", action="store_true", help="discard results already in --out")
    parser.add_argument("--top", type=int, default=12, help="configurations shown in the summary")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--list", action="store_true", help="list presets and axes, and exit")
    parser.set_defaults(handler=run)


def build_spec(args: argparse.Namespace) -> SweepSpec:
    """The spec of the command line: preset or file, then the flags on top."""
    if args.preset is not None and args.spec is not None:
        raise ParameterError("give a preset or --spec FILE, not both")
    if args.preset is not None:
        spec = preset(args.preset)
    elif args.spec is not None:
        spec = SweepSpec.from_toml(args.spec)
    elif args.axis:
        spec = SweepSpec()
    else:
        raise ParameterError(f"nothing to sweep: give a preset ({', '.join(PRESETS)}), --spec FILE or --axis")
    for item in args.axis:
        name, sep, text = item.partition("=")
        if not sep:
            raise ParameterError(f"--axis {item!r}: expected NAME=V1,V2,... (e.g. {ax.BLEND_99}=0.5,1)")
        spec = spec.with_axis(name.strip(), parse_values(name.strip(), text))
    changes: dict[str, Any] = {}
    if args.participants is not None:
        changes["participants"] = args.participants
    if args.repetitions is not None:
        changes["repetitions"] = args.repetitions
    if args.seeds is not None:
        changes["seeds"] = tuple(_int_list("--seeds", args.seeds))
    if args.support is not None:
        changes["conditions"] = parse_support(_split(args.support))
    if args.speeds is not None:
        changes["speeds"] = tuple(_split(args.speeds))
    if args.identification is not None:
        changes["identification"] = args.identification
    if args.bench is not None:
        changes["bench"] = args.bench
    # The flags' values are checked as the spec's (a file's own values were checked as it was read).
    with flag_errors({name: f"--{name}" for name in ("participants", "repetitions", "seeds", "speeds")}):
        return replace(spec, **changes) if changes else spec


def run(args: argparse.Namespace) -> int:
    # Imported here, not at the top: building the parser (bowden --help) needs none of the summary's
    # statistics, nor rich.
    from rich.console import Console

    from bowden.study.progress import StageProgress
    from bowden.sweep.summary import points_table

    # No markup (axis names hold brackets) and no wrapping of long lines on narrow terminals.
    console = Console(markup=False, highlight=False, soft_wrap=True)
    if args.list:
        _print_list(console)
        return 0
    if not 1 <= args.top <= 1000:
        raise ParameterError(f"--top must be in [1, 1000], got {args.top}")
    spec = build_spec(args)
    out = args.out if args.out is not None else Path(f"bowden-sweep-{spec.name}")
    # Dask is imported only now: the rest of bowden works without the cluster extra.
    from bowden.engine.cluster import dask_client
    from bowden.engine.pool import check_workers
    from bowden.sweep.runner import run_sweep

    progress = StageProgress(enabled=not args.quiet)
    with flag_errors({"workers": "--workers"}):
        check_workers(args.workers)
    with dask_client(args.scheduler, args.workers) as client:
        result = run_sweep(spec, out, client, force=args.force, progress=progress)
    console.print(points_table(result.points, spec.axis_names, top=args.top))
    _print_answer(console, result.points)
    for note in result.notes:
        console.print(f"note: {note}")
    console.print(
        f"tasks       {result.tasks_computed} computed, {result.tasks_skipped} already done, "
        f"{result.models_identified} suit(s) identified, {result.workers} worker(s), {result.seconds:.1f} s"
    )
    console.print(f"results     {result.results_path.resolve()}")
    console.print(f"points      {result.points_path.resolve()}")
    return 0


def _print_answer(console: Console, points: Any) -> None:
    from bowden.sweep.summary import PARETO, SPIKE, TENSION

    best_tension = points.loc[points[TENSION].idxmin()]
    best_spike = points.loc[points[SPIKE].idxmin()]
    for label, row in (("lowest tension RMSE", best_tension), ("smallest lowering peak", best_spike)):
        console.print(
            f"{label:<24} θ̇₀₀₁ = {row[ax.BLEND_01]:g}, θ̇₀₉₉ = {row[ax.BLEND_99]:g} rad/s: "
            f"{row[TENSION]:.2f} N, |lowering peak| {row[SPIKE]:.1f} %"
        )
    paper = points[points["paper_blend"]]
    if not paper.empty:
        row = paper.iloc[0]
        label = "paper blend (−1, +1)"
        console.print(f"{label:<24} {row[TENSION]:.2f} N, |lowering peak| {row[SPIKE]:.1f} %")
    front = points[points[PARETO]]
    console.print(f"Pareto front (tension RMSE vs lowering peak): {len(front)} configuration(s)")


def _print_list(console: Console) -> None:
    console.print("presets:")
    for name, spec in PRESETS.items():
        console.print(f"  {name:<16} {len(spec.points())} points × {spec.participants} participants")
    console.print("axes (--axis NAME=V1,V2,... or [axes] in a spec file):")
    for axis in ax.AXES.values():
        console.print(f"  {axis.name:<32} {axis.kind:<10} {axis.description}")


def _split(text: str) -> list[str]:
    return [part.strip() for part in text.split(",") if part.strip()]


def _int_list(flag: str, text: str) -> list[int]:
    try:
        return [int(part) for part in _split(text)]
    except ValueError:
        raise ParameterError(f"{flag}: {text!r} is not a comma-separated list of integers") from None
