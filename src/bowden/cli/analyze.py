"""``bowden analyze``: analysis, statistics and report of a study store (real or simulated)."""

from __future__ import annotations

import argparse
from pathlib import Path

from bowden.errors import StoreError
from bowden.study.analyze import analyze_store
from bowden.study.progress import StageProgress


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "analyze",
        help="analyse a study store: outcome measures, statistics, report",
        description="Analyse every completed trial of a study store (a study directory or its study.db).",
    )
    parser.add_argument("study", type=Path, help="study directory or study.db file")
    parser.add_argument("--report", type=Path, help="report path (default: report.html beside the store)")
    parser.add_argument("--bench", type=Path, help="bench recording, to include the identification figure")
    parser.add_argument("--export", type=Path, help="also export every table to this directory")
    parser.add_argument("--format", choices=("parquet", "csv"), default="parquet", help="export format")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    store = args.study / "study.db" if args.study.is_dir() else args.study
    if not store.exists():
        raise StoreError(f"no study store at {store} (expected a study directory or a study.db file)")
    report = args.report if args.report is not None else store.with_name("report.html")
    bench = args.bench
    if bench is None and (store.parent / "bench.parquet").exists():
        bench = store.parent / "bench.parquet"
    result = analyze_store(store, report, bench_path=bench, progress=StageProgress(enabled=not args.quiet))
    if args.export is not None:
        from bowden.study.store import StudyStore

        with StudyStore(store) as opened:
            files = opened.export(args.export, file_format=args.format)
        print(f"exported {len(files)} tables to {args.export}")
    print(f"analysed {result.n_trials} trials; report {result.report.resolve()}")
    return 0
