"""The gamma dispersion the paper's iEMG condition tests imply, and (optionally) a study's own.

For each muscle and phase of Tables S7-S9 whose condition p-value is printed exactly (not "< 0.001"),
the dispersion φ (Var(y) = φμ²) under which the paper's GLMM, on 17 participants × 3 speeds × 9
repetitions per condition, gives that p on its cell means (the mean of the log over speeds):
``bowden.sim.calibration.implied_dispersion``. With ``--study DIR`` (a ``bowden study`` directory) it
fits the same GLMMs on the study's repetitions and prints their φ beside. This is how the sEMG
amplitude's repetition spread was set (docs/simulation.md, "Amplitude variability").

Usage: ``python scripts/emg_dispersion.py [--study DIR]``
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from bowden.analysis.outcomes import IEMG_PREFIX
from bowden.contracts import CONDITIONS, MUSCLES, SPEEDS
from bowden.sim.calibration import implied_dispersion
from bowden.stats import fit_gamma_glmm
from bowden.store.study_store import StudyStore
from bowden.study.paper_values.iemg_data import IEMG, IEMG_P
from bowden.study.statistics import outcome_data

PARTICIPANTS, REPETITIONS_KEPT = 17, 9
N_PER_CONDITION = PARTICIPANTS * len(SPEEDS) * REPETITIONS_KEPT  # 459
RESIDUAL_DF = N_PER_CONDITION * len(CONDITIONS) - len(CONDITIONS) * len(SPEEDS)  # 1824


def paper_dispersion(phase: str, muscle: str) -> float:
    """φ implied by the paper's condition test of one muscle and phase (nan where p is a bound)."""
    p = IEMG_P[(phase, muscle)][0]
    if p.upper_bound:
        return math.nan
    log_means = [
        float(np.mean([math.log(IEMG[(phase, muscle, s, c)][0]) for s in SPEEDS])) for c in CONDITIONS
    ]
    return implied_dispersion(log_means, p.value, n_per_condition=N_PER_CONDITION, residual_df=RESIDUAL_DF)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", type=Path, help="a bowden study directory (its study.db)")
    args = parser.parse_args()
    outcomes = None
    if args.study is not None:
        with StudyStore(args.study / "study.db") as store:
            outcomes = store.outcomes()
    print("phase     muscle               paper p   paper phi   study phi")
    for phase in ("entire", "raising", "lowering"):
        for muscle in MUSCLES:
            phi = paper_dispersion(phase, muscle)
            study = math.nan
            if outcomes is not None:
                study = fit_gamma_glmm(outcome_data(outcomes, IEMG_PREFIX + muscle, phase)).dispersion
            print(f"{phase:9s} {muscle:20s} {IEMG_P[(phase, muscle)][0]!s:>8s} {phi:10.3f} {study:10.3f}")


if __name__ == "__main__":
    main()
