"""Peak memory of `bowden analyze --export` against the issue's 500 MB bound, before and after;
then the time and peak memory of `bowden export --bids` (issue 29) on the same store.

Run: python benchmarks/export.py [--participants N | --store study.db] [--emg] [--before-rev REV]
Each export runs in a fresh interpreter whose peak resident memory (ru_maxrss) is printed with its
ratio to 500 MB. "before" runs the export module of git revision REV (the one that read each table
whole) on the same trials in the schema-3 layout (benchmarks/store.py writes that copy).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from store import write_legacy_copy

BOUND_MB = 500.0
# The last revision of src/bowden/store/export.py before the export streamed.
BEFORE_REV = "ac507e0"
REPO = Path(__file__).resolve().parent.parent

_AFTER = """
import resource, sys
from bowden.store.study_store import StudyStore
with StudyStore(sys.argv[1]) as store:
    store.export(sys.argv[2], file_format=sys.argv[3], include_emg=sys.argv[4] == "1")
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""
_BEFORE = """
import resource, sys, types
from bowden.store.study_store import StudyStore
old = types.ModuleType("old_export")
exec(compile(open(sys.argv[5]).read(), "old_export.py", "exec"), old.__dict__)
with StudyStore(sys.argv[1]) as store:
    old.export_store(store, sys.argv[2], file_format=sys.argv[3], include_emg=sys.argv[4] == "1")
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""

_BIDS = """
import resource, sys
from bowden.share.bids import export_bids
from bowden.store.study_store import StudyStore
with StudyStore(sys.argv[1]) as store:
    export_bids(store, sys.argv[2])
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def run(code: str, store: Path, out: Path, file_format: str, emg: bool, *extra: str) -> tuple[float, float]:
    """Peak MB and seconds of one export in a child process."""
    start = time.perf_counter()
    command = [sys.executable, "-c", code, str(store), str(out), file_format, "1" if emg else "0", *extra]
    result = subprocess.run(command, capture_output=True, text=True, check=True)
    return int(result.stdout.strip()) / 1024, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--participants", type=int, default=17)
    parser.add_argument("--store", type=Path, help="export this store instead of running a study")
    parser.add_argument("--emg", action="store_true", help="export the raw sEMG too (--export-emg)")
    parser.add_argument("--before-rev", default=BEFORE_REV, help="git revision of the old export")
    parser.add_argument("--no-before", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        store = args.store
        if store is None:
            from bowden.study.pipeline import StudySettings, run_study

            store = run_study(StudySettings(participants=args.participants), work / "study", force=True).store
        print(f"store {store.stat().st_size / 1e6:.0f} MB" + (", with the raw sEMG" if args.emg else ""))
        legacy = work / "legacy.db"
        old_export = work / "old_export.py"
        if not args.no_before:
            write_legacy_copy(store, legacy)
            show = ["git", "-C", str(REPO), "show", f"{args.before_rev}:src/bowden/store/export.py"]
            source = subprocess.run(show, capture_output=True, text=True, check=True).stdout
            old_export.write_text(source)
        for file_format in ("parquet", "csv"):
            after, seconds = run(_AFTER, store, work / f"after-{file_format}", file_format, args.emg)
            size = sum(p.stat().st_size for p in (work / f"after-{file_format}").iterdir()) / 1e6
            line = (f"{file_format:<8} after  peak {after:7.0f} MB  ratio to {BOUND_MB:.0f} MB "
                    f"{after / BOUND_MB:.2f}  ({seconds:.1f} s, {size:.0f} MB written)")
            if not args.no_before:
                before, old_s = run(_BEFORE, legacy, work / f"before-{file_format}", file_format, args.emg,
                                    str(old_export))
                line += (f"\n{'':<8} before peak {before:7.0f} MB  ratio {before / BOUND_MB:.2f}  "
                         f"({old_s:.1f} s); after/before {after / before:.2f}")
            print(line)
        bids = work / "bids"
        peak, seconds = run(_BIDS, store, bids, "bids", True)
        size = sum(p.stat().st_size for p in bids.rglob("*") if p.is_file()) / 1e6
        print(f"{'bids':<8} export --bids  peak {peak:7.0f} MB  ({seconds:.1f} s, {size:.0f} MB written)")


if __name__ == "__main__":
    main()
