"""``bowden study``: the whole paper end to end on the simulated suit (the main job)."""

from __future__ import annotations

import argparse
from pathlib import Path

from bowden.cli._flag_errors import flag_errors


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "study",
        help="run the paper end to end on a simulated suit and a virtual cohort, and write the report",
        description=(
            "Simulate the mannequin bench, identify the transmission, run the study protocol on a virtual "
            "cohort (no suit, pretension, 25 % and 50 % support at three speeds), analyse it, fit the "
            "statistics and write an HTML report. Resumes an interrupted run in the same --out directory. "
            "The trials and their analysis run on one worker process per core (--workers) or on a Dask "
            "cluster (--scheduler); the results are the same either way."
        ),
    )
    parser.add_argument("--participants", type=int, default=17, help="cohort size (paper: 17)")
    parser.add_argument("--seed", type=int, default=0, help="seed of everything random (default 0)")
    parser.add_argument("--repetitions", type=int, default=10, help="cycles per trial (paper: 10)")
    parser.add_argument("--out", type=Path, default=Path("bowden-study"), help="study directory")
    parser.add_argument("--quick-bench", action="store_true", help="a reduced identification protocol")
    parser.add_argument("--no-emg", action="store_true", help="do not keep raw sEMG in the store")
    parser.add_argument(
        "--force", action="store_true",
        help="redo every stage from scratch, replacing only what this command wrote in --out (a file it "
        "did not write, such as a lab's own model.json, or a store holding trials it did not record, "
        "such as live recordings, is refused even then)",
    )
    parser.add_argument(
        "--compensation", choices=("paper", "dynamic"), default="paper",
        help="the paper's friction compensation (default) or the dynamic one identified from the same bench",
    )
    parser.add_argument(
        "--muscles", choices=("simple", "musculoskeletal"), default="simple",
        help="muscle activations from the hand-made model (default) or from MyoArm's mechanics and static "
        "optimisation (needs the msk extra: pip install 'bowden[msk]')",
    )
    engine = parser.add_mutually_exclusive_group()
    engine.add_argument(
        "--workers", type=int, metavar="N",
        help="worker processes on this machine (default: one per core; 1: no worker processes)",
    )
    engine.add_argument(
        "--scheduler", metavar="ADDRESS",
        help="run the trials and their analysis on the Dask scheduler at ADDRESS (tcp://host:8786; "
        "needs the cluster extra: pip install 'bowden[cluster]')",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    if args.scheduler is not None:  # refused before the study's imports (4 s) when Dask is missing
        from bowden.engine.cluster import require_dask

        require_dask("bowden study --scheduler")
    # Imported here, not at the top: building the parser (bowden --help) needs none of the study.
    from bowden.engine.pool import check_workers
    from bowden.study.pipeline import StudySettings, run_study
    from bowden.study.progress import StageProgress

    # The settings and the pool check their fields; the refusals name the flags instead.
    with flag_errors({name: f"--{name}" for name in ("participants", "seed", "repetitions", "workers")}):
        settings = StudySettings(
            participants=args.participants,
            seed=args.seed,
            repetitions=args.repetitions,
            quick_bench=args.quick_bench,
            store_emg=not args.no_emg,
            compensation=args.compensation,
            muscles=args.muscles,
        )
        check_workers(args.workers)
    result = run_study(
        settings,
        args.out,
        force=args.force,
        progress=StageProgress(enabled=not args.quiet),
        workers=args.workers,
        scheduler=args.scheduler,
    )
    print(f"study directory  {result.directory}")
    print(f"trials           {result.trials_simulated} simulated, {result.trials_skipped} already done")
    print(f"workers          {result.workers}")
    for stage, seconds in result.stage_seconds.items():
        print(f"  {stage:<32} {seconds:6.1f} s")
    if result.analysis is not None and result.analysis.statistics.failures:
        print(f"models not fitted: {len(result.analysis.statistics.failures)} (see the report's notes)")
    print(f"report           {result.report.resolve()}")
    return 0
