"""The analysis on the simulated cohort (bowden.sim) reproduces the simulation's known behaviour.

The simulated participants are built so that the agonists' activation falls as the suit carries
more of the arm, and the simulated transmission tracks tension worse with more support and while
lowering (friction reverses at the turn). The analysis knows none of this: it sees the trial
DataFrames and the raw 2 kHz sEMG (with ECG on the trunk muscles), like real data.
"""

import pytest

from bowden.analysis import TrialMetadata, analyse_study
from bowden.model import CompensationLine, CompensationModel
from bowden.model.transmission import slopes_from_friction
from bowden.sim import ProtocolSettings, generate_cohort, simulate_cohort
from bowden.sim.parameters import SheathParameters

# The lines of the default simulated suit (its quasi-static slopes; intercepts near the bench's).
_RAISING_SLOPE, _LOWERING_SLOPE = slopes_from_friction(SheathParameters().kinetic_coefficient, 0.035)
MODEL = CompensationModel(
    raising=CompensationLine(intercept_nm=0.11, slope_m=_RAISING_SLOPE),
    lowering=CompensationLine(intercept_nm=-0.11, slope_m=_LOWERING_SLOPE),
)
AGONISTS = ("anterior_deltoid", "medial_deltoid", "trapezius", "pectoralis_major")


@pytest.fixture(scope="module")
def study():
    # Two participants at one speed: the muscles' known behaviour, without the sEMG amplitude's
    # spread from trial to trial and repetition to repetition (which needs the whole cohort to
    # average out; tests/sim/test_emg_amplitude.py tests it).
    participants = generate_cohort(0, emg_trial_sd=0.0, emg_repetition_sd=0.0)[:2]
    cohort = simulate_cohort(participants, model=MODEL, settings=ProtocolSettings(speeds=("V3",)), seed=1)
    trials = [
        (
            TrialMetadata(participant=t.participant.participant_id, condition=t.condition, speed=t.speed),
            t.to_pandas(),
            t.emg(),
        )
        for t in cohort
    ]
    return analyse_study(trials)


def _means(outcomes, measure):
    rows = outcomes[outcomes.measure == measure]
    return rows.groupby(["phase", "condition"])["value"].mean()


def test_agonist_iemg_falls_with_support(study):
    for muscle in AGONISTS:
        iemg = _means(study.outcomes, f"iemg_{muscle}")
        for phase in ("raising", "lowering"):
            series = [iemg[(phase, c)] for c in ("no_suit", "pretension", "support_25", "support_50")]
            assert series[3] < series[2] < series[1] < series[0], (muscle, phase, series)
            assert series[3] < 0.85 * series[0], (muscle, phase, series)


def test_tension_rmse_table_has_the_papers_layout_and_trends(study):
    table = study.rmse_table("tension_rmse_n")
    assert list(table.index) == ["pretension", "support_25", "support_50"]
    assert list(table.columns) == [("V3", "entire"), ("V3", "raising"), ("V3", "lowering")]
    entire = table[("V3", "entire")]
    assert entire["pretension"] < entire["support_25"] < entire["support_50"]
    assert (table[("V3", "lowering")] > table[("V3", "raising")]).all()
    peak_time = _means(study.outcomes, "peak_percent_error_time_pct")
    for condition in ("pretension", "support_25", "support_50"):
        assert 50.0 < peak_time[("lowering", condition)] < 75.0  # the error spike after the turn


def test_every_trial_is_segmented_on_its_reference_and_ecg_is_found(study):
    assert study.info.segmentation_sources == {"reference": 8}
    assert study.info.n_repetitions == 8 * 9
    assert 40.0 < study.info.heart_rate_bpm["pectoralis_major"] < 120.0
    sparc = _means(study.outcomes, "sparc")
    assert all(-4.0 < value < -1.0 for value in sparc.values)
