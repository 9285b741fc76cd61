"""Check the virtual cohort against the paper's human findings, quickly, for calibrating the participants.

Simulates a cohort with the default study's protocol (no EMG synthesis: iEMG from the muscle
activations, which is what the synthetic EMG's envelope follows, plus the amplifier's noise floor),
then prints, beside the paper's values (abstract and Results):

* the change in raising iEMG at 50 % support against no suit (anterior deltoid, trapezius, pectoralis
  major: −30/−38/−38 %) and in lowering iEMG of the posterior deltoid (+32 %);
* the elevation RMSE per condition and the p-value of the condition term (paper: not significant);
* SPARC per condition (paper: smoothness falls from no suit to 50 %).

The numbers that decide are those of the full pipeline (``bowden study``'s report, "Where the
simulation departs from the paper"); this script is the fast loop used to choose the participants'
parameters, and docs/simulation.md states what came out of it.

Usage: ``python scripts/participant_calibration.py [--seed 0] [--participants 17] [--workers 2]``
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import math
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import pandas as pd

from bowden import contracts as c
from bowden.analysis.outcomes import ELEVATION_RMSE, OUTCOME_COLUMNS, SPARC
from bowden.analysis.trial_outcomes import TrialMetadata, analyse_trial
from bowden.identify import TransmissionIdentifier
from bowden.model import CompensationModel
from bowden.sim.batch import ProtocolSettings, condition_order, session_trial, simulate_trial, trial_seed
from bowden.sim.bench import run_bench
from bowden.sim.calibration import activation_iemg_rows, iemg_changes
from bowden.sim.participants import VirtualParticipant, generate_cohort
from bowden.stats.analysis import analyse_outcome
from bowden.study.statistics import outcome_data

PAPER_RAISING_50 = {"anterior_deltoid": -30.0, "trapezius": -38.0, "pectoralis_major": -38.0}
PAPER_LOWERING_50 = {"posterior_deltoid": 32.0}


def _participant_rows(
    item: tuple[int, VirtualParticipant], model: CompensationModel, seed: int
) -> tuple[list[dict[str, Any]], list[pd.DataFrame]]:
    index, participant = item
    settings = ProtocolSettings()
    iemg_rows: list[dict[str, Any]] = []
    outcome_frames = []
    order = condition_order(seed, index, c.CONDITIONS)
    for condition in order:
        for speed in c.SPEEDS:
            trial = simulate_trial(
                participant, condition, speed, model=model, settings=settings,
                seed=trial_seed(seed, index, condition, speed),
                session_trial=session_trial(order, condition, c.SPEEDS, speed),
            )
            meta = TrialMetadata(participant=participant.participant_id, condition=condition, speed=speed)
            rows = analyse_trial(meta, trial.to_pandas()).rows
            outcome_frames.append(pd.DataFrame.from_records(rows, columns=list(OUTCOME_COLUMNS)))
            iemg_rows.extend(activation_iemg_rows(trial))
    return iemg_rows, outcome_frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--participants", type=int, default=17)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--set", action="append", default=[], metavar="FIELD=VALUE",
        help="override a VirtualParticipant field for every participant (repeatable)",
    )
    args = parser.parse_args()
    model = TransmissionIdentifier().fit(run_bench(seed=args.seed)).model_
    overrides = {name: float(value) for name, value in (item.split("=", 1) for item in args.set)}
    drawn = generate_cohort(args.seed, n_participants=args.participants)
    cohort = tuple(dataclasses.replace(p, **overrides) for p in drawn)
    work = functools.partial(_participant_rows, model=model, seed=args.seed)
    with ProcessPoolExecutor(args.workers) as pool:
        parts = list(pool.map(work, enumerate(cohort)))
    rows = pd.DataFrame([row for part in parts for row in part[0]])
    outcomes = pd.concat([frame for part in parts for frame in part[1]], ignore_index=True)
    changes = iemg_changes(rows).set_index(["phase", "muscle", "condition"])
    pd.set_option("display.width", 160)
    print("iEMG change against no suit, % (mean over speeds; V1/V2/V3)")
    for phase, paper in (("raising", PAPER_RAISING_50), ("lowering", PAPER_LOWERING_50)):
        for muscle, value in paper.items():
            row = changes.loc[(phase, muscle, c.CONDITION_SUPPORT_50)]
            print(f"  {phase:<8} {muscle:<18} 50 %: {row['change_pct']:+6.1f} "
                  f"({row['V1']:+.0f}/{row['V2']:+.0f}/{row['V3']:+.0f})  paper {value:+.0f}")
    print(changes["change_pct"].unstack("condition").round(1).to_string())
    for measure, label in ((ELEVATION_RMSE, "elevation RMSE (deg)"), (SPARC, "SPARC (−)")):
        data = outcome_data(outcomes, measure, "entire")
        table = data.groupby(["condition", "speed"])["value"].mean().unstack("speed")
        fit = analyse_outcome(data, label)
        p = fit.tests["p"].astype(float)
        print(f"{label}: p(condition) = {p.get('condition', math.nan):.3g}, "
              f"p(speed) = {p.get('speed', math.nan):.3g}")
        print(table.reindex(c.CONDITIONS).round(3).to_string())
        spread = data.groupby(["participant", "condition", "speed"])["value"].agg(["std", "mean"])
        print(f"  repetition-to-repetition CV within a trial: {(spread['std'] / spread['mean']).mean():.3f}")


if __name__ == "__main__":
    main()
