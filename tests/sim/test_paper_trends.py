"""The simulated study reproduces the paper's qualitative tension-tracking results (issue: done when).

One run of the default suit and cohort (17 participants, seed 0), with the controller identified on the
simulated bench, as `benchmarks/simulation.py --table` prints it but with 4 repetitions per trial, not
10: the cell means are averages over repetitions that differ only by their noise and excursion, so
3 kept repetitions (the first is dropped, as in the paper) give them within 2 % of 9's (measured on
every cell; the peak times within a point), at 45 % of the simulation's cost. The paper's values come from
`bowden.study.paper_values` (its Table `torque_tension_tracking_RMSE_combined`).
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pandas as pd
import pytest

from bowden import contracts as c
from bowden.identify import TransmissionIdentifier
from bowden.sim import generate_cohort, run_bench, simulate_cohort
from bowden.sim.batch import ProtocolSettings
from bowden.sim.calibration import activation_iemg_rows, iemg_changes
from bowden.sim.results import TRUE_TENSION, CohortSimulation, phase_masks, rmse
from bowden.study import paper_values

SUPPORTED = (c.CONDITION_PRETENSION, c.CONDITION_SUPPORT_25, c.CONDITION_SUPPORT_50)
PAPER_TENSION_RMSE_N = paper_values.tension_rmse_n()


@pytest.fixture(scope="module")
def study() -> CohortSimulation:
    # The paper's lines only: the trials run the paper's compensation (ProtocolSettings' default),
    # which never reads the model's dynamic part (the trials are bit-identical with it), and
    # identifying that part took most of the fit's time.
    model = TransmissionIdentifier(dynamic=False).fit(run_bench(seed=0)).model_
    # The muscles' mechanism without the sEMG amplitude's spread (tested on its own in
    # test_emg_amplitude.py): with 3 kept repetitions it would move a change by ±8 points.
    cohort = generate_cohort(0, emg_trial_sd=0.0, emg_repetition_sd=0.0)
    return simulate_cohort(cohort, model=model, seed=0, settings=ProtocolSettings(repetitions=4))


@pytest.fixture(scope="module")
def cells(study: CohortSimulation) -> dict[str, dict[tuple[str, str], float]]:
    values: dict[str, dict[tuple[str, str], list[float]]] = defaultdict(lambda: defaultdict(list))
    for trial in study.trials:
        if not trial.wears_suit:
            continue
        desired, true = trial[c.TRIAL_DESIRED_TENSION], trial[TRUE_TENSION]
        for phase, mask in phase_masks(trial).items():
            values[phase][(trial.condition, trial.speed)].append(rmse(true[mask], desired[mask]))
        frac, rep = trial.cycle_fraction(), trial.repetition_index()
        percent = (true - desired) / desired
        for r in range(1, trial.repetitions):  # the first repetition is dropped, as in the paper
            lowering = (rep == r) & (frac >= 0.5)
            values["peak_time"][(trial.condition, trial.speed)].append(
                100.0 * float(frac[lowering][np.argmax(percent[lowering])])
            )
    return {name: {cell: float(np.mean(v)) for cell, v in by_cell.items()}
            for name, by_cell in values.items()}


def test_tension_error_grows_with_support_and_with_speed(cells) -> None:
    entire = np.array([[cells["entire"][(cond, speed)] for speed in c.SPEEDS] for cond in SUPPORTED])
    assert np.all(np.diff(entire, axis=0) > 0), entire  # pretension < 25 % < 50 % at every speed
    assert np.all(np.diff(entire, axis=1) > 0), entire  # V1 < V2 < V3 in every condition


def test_lowering_error_exceeds_raising_error_everywhere(cells) -> None:
    for cell, lowering in cells["lowering"].items():
        assert lowering > cells["raising"][cell], cell


def test_error_sizes_are_the_papers(cells) -> None:
    for cond in SUPPORTED:
        for speed in c.SPEEDS:
            paper = float(PAPER_TENSION_RMSE_N.loc[cond, (speed, "entire")])
            assert 0.8 * paper < cells["entire"][(cond, speed)] < 1.25 * paper, (cond, speed)
    assert 2.0 < cells["entire"][(c.CONDITION_PRETENSION, "V1")] < 4.0
    for speed in c.SPEEDS:
        assert 5.0 < cells["entire"][(c.CONDITION_SUPPORT_50, speed)] < 10.0


def test_largest_lowering_error_follows_the_turn(cells) -> None:
    # Lowering starts at 50 % of the cycle; the paper's peaks are at 60.5-74.1 % (Table S3), each
    # with an SD of 5-18 points across repetitions; a mean inside that range follows the turn.
    for cell, time_pct in cells["peak_time"].items():
        assert 55.0 < time_pct < 75.0, cell


def test_muscles_change_as_the_papers_did(study: CohortSimulation) -> None:
    # The abstract: at 50 % support the anterior deltoid, trapezius and pectoralis major work 30, 38
    # and 38 % less while raising, the posterior deltoid 32 % more while lowering (issue 18's bounds:
    # within 10 points, and +15 to +50 %). iEMG read off the activations (bowden.sim.calibration).
    rows = pd.DataFrame([row for trial in study.trials for row in activation_iemg_rows(trial)])
    change = iemg_changes(rows).set_index(["phase", "muscle", "condition"])["change_pct"]
    for muscle, paper in (("anterior_deltoid", -30.0), ("trapezius", -38.0), ("pectoralis_major", -38.0)):
        assert abs(change[("raising", muscle, c.CONDITION_SUPPORT_50)] - paper) <= 10.0, muscle
    assert 15.0 <= change[("lowering", "posterior_deltoid", c.CONDITION_SUPPORT_50)] <= 50.0
