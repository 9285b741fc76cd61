"""The paper's compensation against the dynamic one on a family of simulated suits (issues 17, 28).

Each suit runs the paper's bench protocol, is identified by ``bowden identify``'s estimator, and then
the same virtual participants perform the same trials with either compensation. Printed: per suit the
tension RMSE and the lowering-onset peak of both (averaged over participants, conditions and speeds)
and the ratios dynamic/paper, measured in this one run; then the targets of the issue:
RMSE ratio ≤ 0.6 and peak ratio ≤ 0.5 averaged over the family, and no (condition, speed) cell of any
suit where the dynamic compensation's RMSE is worse.

``--family structural`` (the default, issue 28) judges on suits whose friction and motor differ from
the compensation's law in *structure* (:mod:`bowden.sim.plant_family_structural`: Dahl presliding,
capstan, Stribeck shapes, load-dependent drag, sheath play and compliance, a torque constant drifting
warm, IMU latency 5–80 ms and noise ×1–3; ranges committed before any evaluation) with the whole
cohort, and prints every (suit, condition, speed) cell, the mean ratios and the worst cell against the
issue's targets: mean RMSE ≤ 0.60×, mean lowering-onset peak ≤ 0.50× the paper's, no cell worse than
the paper's by more than 5 %. ``--family parametric`` is issue 17's family: "default" is the suit the
dynamic compensation was developed on, the other named suits vary its parameters.
``--random N`` adds suits drawn from the family's ranges with a seed nobody chose in advance (the
current time unless ``--seed``).

Run: python benchmarks/compensation.py [--family structural] [--participants 17] [--random 6] [--seed S]
     [--plants a,b]
"""

from __future__ import annotations

import argparse
import time

import pandas as pd

from bowden.sim.participants import PAPER_COHORT_SIZE
from bowden.sim.plant_family import DEVELOPMENT_PLANT, named_plants, random_plants
from bowden.sim.plant_family_structural import random_structural_plants, structural_plants
from bowden.study.compensation.comparison import (
    WORSE_TOLERANCE,
    ComparisonSettings,
    cell_table,
    compare_compensations,
    summarise,
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--family", choices=("structural", "parametric"), default="structural")
    parser.add_argument("--participants", type=int, default=PAPER_COHORT_SIZE)
    parser.add_argument("--random", type=int, default=6, help="suits drawn at random (0: none)")
    parser.add_argument("--seed", type=int, default=None, help="seed of the random suits (default: the time)")
    parser.add_argument("--plants", help="only these named suits, comma-separated")
    args = parser.parse_args()

    structural = args.family == "structural"
    plants = list(structural_plants() if structural else named_plants())
    if args.plants:
        wanted = set(args.plants.split(","))
        plants = [plant for plant in plants if plant.name in wanted]
    seed = args.seed if args.seed is not None else int(time.time()) % 2**32
    if args.random:
        plants += (random_structural_plants if structural else random_plants)(args.random, seed)
    started = time.perf_counter()
    rows = compare_compensations(
        plants,
        ComparisonSettings(participants=args.participants),
        progress=lambda plant: print(f"  {plant.name}: {plant.description}", flush=True),
    )
    table = summarise(rows)
    pd.set_option("display.width", 200)
    columns = ["plant", "tension_rmse_n_paper", "tension_rmse_n_dynamic", "rmse_ratio",
               "onset_peak_pct_paper", "onset_peak_pct_dynamic", "peak_ratio",
               "onset_dip_pct_paper", "onset_dip_pct_dynamic", "worse_conditions", "worse_peak_conditions"]
    print(table[columns].round(3).to_string(index=False))
    held_out = table[table["plant"] != DEVELOPMENT_PLANT]
    for label, part in (("whole family", table), ("held out (all but default)", held_out)):
        rmse = part["tension_rmse_n_dynamic"].mean() / part["tension_rmse_n_paper"].mean()
        peak = part["onset_peak_pct_dynamic"].mean() / part["onset_peak_pct_paper"].mean()
        print(f"{label}: RMSE ratio {rmse:.3f} (target ≤ 0.6), lowering-onset peak ratio {peak:.3f} "
              f"(target ≤ 0.5); worst suit RMSE ratio {part['rmse_ratio'].max():.3f}, "
              f"peak ratio {part['peak_ratio'].max():.3f}")
    print("dynamic compensation everywhere:")
    print_cells(cell_table(rows))
    choices = rows.groupby("plant", sort=False)["recommended_why"].first()
    for plant, why in choices.items():
        print(f"  {plant}: {why}")
    print("the compensation the bench's study-like segment recommends per (support, speed) cell "
          "(the paper's where it picks it):")
    print_cells(cell_table(rows, "recommended"))
    print(f"random suits' seed: {seed}; {len(plants)} suits in {time.perf_counter() - started:.0f} s")


def print_cells(cells: pd.DataFrame) -> None:
    """Every (suit, condition, speed) cell, then the means over cells and the worst cell."""
    cells = cells.rename(columns=lambda name: name.replace("_recommended", "_dynamic"))
    print(cells.round(3).to_string(index=False))
    rmse = cells["tension_rmse_n_dynamic"].mean() / cells["tension_rmse_n_paper"].mean()
    peak = cells["onset_peak_pct_dynamic"].mean() / cells["onset_peak_pct_paper"].mean()
    print(f"over {len(cells)} cells: mean RMSE ratio {rmse:.3f} (target ≤ 0.60; mean of cell ratios "
          f"{cells['rmse_ratio'].mean():.3f}), mean lowering-onset peak ratio {peak:.3f} (target ≤ 0.50; "
          f"mean of cell ratios {cells['peak_ratio'].mean():.3f})")
    for ratio, label in (("rmse_ratio", "RMSE"), ("peak_ratio", "lowering-onset peak")):
        worst = cells.loc[cells[ratio].idxmax()]
        print(f"worst cell by {label}: {worst['plant']} {worst['condition']} {worst['speed']}: "
              f"{worst[ratio]:.3f}× the paper's")
    print(f"cells worse than the paper's by more than {100 * WORSE_TOLERANCE:.0f} % (RMSE or peak): "
          f"{int(cells['worse'].sum())} of {len(cells)} (target 0)")


if __name__ == "__main__":
    main()
