"""``bowden analyze``: analysis, statistics and report of a study store (real or simulated)."""

from __future__ import annotations

import argparse
from pathlib import Path

from bowden.cli._outputs import check_output_directory, check_output_file, refuse_overwriting_inputs
from bowden.errors import ParameterError, StoreError
from bowden.store.schema import STORE_FILE_NAME


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "analyze",
        help="analyse a study store: outcome measures, statistics, report",
        description="Analyse every completed trial of a study store (a study directory or its study.db).",
    )
    parser.add_argument("study", type=Path, help="study directory or study.db file")
    parser.add_argument("--report", type=Path, help="report path (default: report.html beside the store)")
    parser.add_argument("--bench", type=Path, help="bench recording, to include the identification figure")
    parser.add_argument(
        "--export",
        type=Path,
        metavar="DIR",
        help="also export the tables to DIR, one file each: participants, trials, samples, events, "
        "questionnaires, outcomes, artifacts (the raw sEMG only with --export-emg), and glmm.R, the R "
        "script that refits the report's GLMMs from the outcomes table",
    )
    parser.add_argument(
        "--export-emg",
        action="store_true",
        help="with --export, also export the raw sEMG (emg table, one row per EMG sample: large)",
    )
    parser.add_argument(
        "--format", choices=("parquet", "csv"), default="parquet",
        help="export format (default: parquet; both are written a chunk at a time, in bounded memory)",
    )
    parser.add_argument(
        "--workers", type=int, metavar="N",
        help="worker processes analysing the trials (default: one per core, but one per ten trials at "
        "most: a worker takes seconds to start; 1: in this process)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    # Imported here, not at the top: building the parser (bowden --help) needs none of the analysis.
    from bowden.engine.pool import MAX_WORKERS
    from bowden.share.r_script import r_script_path, write_r_script
    from bowden.store.export import export_paths
    from bowden.study.analyze import analyze_store
    from bowden.study.progress import StageProgress
    from bowden.study.report.html import check_report_path

    store = args.study / STORE_FILE_NAME if args.study.is_dir() else args.study
    if not store.exists():
        raise StoreError(
            f"no study store at {store} "
            f"(expected a study directory holding {STORE_FILE_NAME}, or a store file)"
        )
    if args.export_emg and args.export is None:
        raise ParameterError("--export-emg needs --export DIR")
    if args.workers is not None and not 1 <= args.workers <= MAX_WORKERS:
        raise ParameterError(f"--workers must be an integer in [1, {MAX_WORKERS}], got {args.workers}")
    report = args.report if args.report is not None else store.with_name("report.html")
    bench = args.bench
    if bench is None and (store.parent / "bench.parquet").exists():
        bench = store.parent / "bench.parquet"
    # Every output is checked before the analysis runs: a bad path costs neither an input nor the time.
    inputs = _inputs(store, bench)
    refuse_overwriting_inputs("--report", report, inputs)
    check_output_file("the report (--report)", report, create_parents=True)
    check_report_path(report)
    if args.export is not None:
        refuse_overwriting_inputs("--export", args.export, inputs)
        check_output_directory("the export (--export)", args.export)
        written = {**inputs, report: "the --report file"}
        for path in export_paths(args.export, file_format=args.format, include_emg=args.export_emg):
            refuse_overwriting_inputs("--export", path, written)
        refuse_overwriting_inputs("--export", r_script_path(args.export), written)
    result = analyze_store(store, report, bench_path=bench, workers=args.workers,
                           progress=StageProgress(enabled=not args.quiet))
    if args.export is not None:
        from bowden.store.study_store import StudyStore

        with StudyStore(store) as opened:
            files = opened.export(args.export, file_format=args.format, include_emg=args.export_emg)
        # The R script that refits the report's GLMMs from the outcomes table, beside it.
        script = write_r_script(args.export, file_format=args.format)
        print(f"exported {len(files)} tables to {args.export}, and {script.name} (Rscript {script}) "
              "that refits the report's GLMMs in R")
    skipped = f", skipped {len(result.skipped)} (see the report's notes)" if result.skipped else ""
    print(f"analysed {result.n_trials} trials{skipped}; report {result.report.resolve()}")
    return 0


def _inputs(store: Path, bench: Path | None) -> dict[Path, str]:
    """The files the analysis reads (SQLite keeps a store's recent commits beside it)."""
    inputs = {
        store: "the study store",
        store.with_name(store.name + "-wal"): "the study store's write-ahead log",
        store.with_name(store.name + "-shm"): "the study store's shared-memory index",
        store.with_name(store.name + "-journal"): "the study store's rollback journal",
    }
    if bench is not None:
        inputs[bench] = "the bench recording"
    return inputs
