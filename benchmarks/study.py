"""Time each stage of the default `bowden study` (17 participants, the paper's protocol).

Run: python benchmarks/study.py [--participants N] [--keep DIR]
Prints seconds per stage and the total against the issue's budget (≤ 180 s here, goal ≤ 60 s).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from bowden.study.pipeline import StudySettings, run_study


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--participants", type=int, default=17)
    parser.add_argument("--keep", type=Path, help="study directory to keep (default: a temporary one)")
    args = parser.parse_args()
    settings = StudySettings(participants=args.participants)
    with tempfile.TemporaryDirectory() as tmp:
        out = args.keep if args.keep is not None else Path(tmp)
        start = time.perf_counter()
        result = run_study(settings, out, force=True)
        total = time.perf_counter() - start
        size_mb = result.store.stat().st_size / 1e6
    for stage, seconds in result.stage_seconds.items():
        print(f"{stage:<34} {seconds:7.1f} s  ({seconds / total:5.1%})")
    print(
        f"{'total':<34} {total:7.1f} s  ratio to the 180 s budget {total / 180:.2f}, "
        f"to the 60 s goal {total / 60:.2f}"
    )
    print(f"study store {size_mb:.0f} MB, {result.trials_simulated} trials")


if __name__ == "__main__":
    main()
