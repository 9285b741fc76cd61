"""Fit every model of a study: 8 muscles x 3 phases (iEMG) + elevation RMSE + SPARC = 26 gamma GLMMs.

    .venv/bin/python benchmarks/stats.py [--methods pql-reml laplace agq]

Each model is fitted to its own simulated 17 participants x 4 conditions x 3 speeds x 9 repetitions
(1836 rows), with Type-III tests and all pairwise comparisons (what `bowden analyze` needs). Prints the
time of the whole study per method, the time per model, and the ratio to the 30 s target of issue 7.
"""

from __future__ import annotations

import argparse
import time

from bowden.contracts import MUSCLES, PHASES
from bowden.stats import AnalysisOptions, GlmmOptions, analyse_outcome, simulate_gamma_glmm

TARGET_S = 30.0


def study_outcomes() -> list[str]:
    return [f"{m}/{p}" for m in MUSCLES for p in PHASES] + ["elevation_rmse", "sparc"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--methods", nargs="+", default=["pql-reml", "laplace", "agq"])
    args = parser.parse_args()
    names = study_outcomes()
    data = [simulate_gamma_glmm(seed=k) for k in range(len(names))]
    print(f"{len(names)} models, {len(data[0])} rows each")
    for method in args.methods:
        options = AnalysisOptions(glmm=GlmmOptions(method=method))
        start = time.perf_counter()
        for name, frame in zip(names, data, strict=True):
            analyse_outcome(frame, name, options=options)
        total = time.perf_counter() - start
        print(
            f"{method:>9}: {total:7.2f} s total, {1e3 * total / len(names):7.1f} ms per model, "
            f"{total / TARGET_S:.3f} of the {TARGET_S:.0f} s target"
        )


if __name__ == "__main__":
    main()
