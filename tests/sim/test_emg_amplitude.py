"""The sEMG amplitude's variability beyond the carrier: one mean-one log-normal factor per trial and
muscle, one per repetition and muscle (sim/emg.py, amplitude_factors; docs/simulation.md,
"Amplitude variability"), against hand-derived values."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats
from tests.module_from_path import load_module

from bowden.contracts import MUSCLES
from bowden.errors import ParameterError
from bowden.model import CompensationModel
from bowden.sim.batch import ProtocolSettings, simulate_trial
from bowden.sim.calibration import activation_iemg_rows, implied_dispersion
from bowden.sim.emg import amplitude_factors, emg_synthesize
from bowden.sim.participants import EMG_REPETITION_SD, EMG_TRIAL_SD, generate_cohort


def _lognormal_cv(log_sd: float) -> float:
    # The coefficient of variation of a log-normal variable: sqrt(exp(s²) − 1).
    return math.sqrt(math.expm1(log_sd**2))


def test_repetition_factors_have_the_configured_spread_and_mean_one() -> None:
    # 2000 repetitions of 5 samples (and a lead-in) × 8 muscles: 16,000 independent draws.
    index = np.concatenate([np.full(7, -1), np.repeat(np.arange(2000), 5)])
    factors = amplitude_factors(index, trial_sd=0.0, repetition_sd=EMG_REPETITION_SD, seed=11)
    assert factors.shape == (index.size, len(MUSCLES))
    np.testing.assert_array_equal(factors[:7], 1.0)  # outside the movement: the trial's factor (1 here)
    per_repetition = factors[7::5]
    assert np.all(factors[7:].reshape(2000, 5, -1) == per_repetition[:, None, :])  # constant within one
    n = per_repetition.size
    log = np.log(per_repetition)
    # log-SD s within its sampling error (s/sqrt(2n) ≈ 0.0035), mean exp(-s²/2 + s²/2) = 1: the
    # log's mean is −s²/2 (−0.198) within s/sqrt(n) ≈ 0.005.
    assert abs(log.std(ddof=1) - EMG_REPETITION_SD) < 4 * EMG_REPETITION_SD / math.sqrt(2 * n)
    assert abs(log.mean() + 0.5 * EMG_REPETITION_SD**2) < 4 * EMG_REPETITION_SD / math.sqrt(n)
    # The factors' own CV is the log-normal's, sqrt(exp(0.63²) − 1) = 0.698, within 5 %.
    cv = per_repetition.std(ddof=1) / per_repetition.mean()
    assert cv == pytest.approx(_lognormal_cv(EMG_REPETITION_SD), rel=0.05)
    assert per_repetition.mean() == pytest.approx(1.0, abs=4 * cv / math.sqrt(n))


def test_the_trial_factor_is_one_per_trial_and_muscle_with_the_configured_spread() -> None:
    index = np.concatenate([np.full(3, -1), np.repeat(np.arange(4), 6)])
    trials = np.array([
        amplitude_factors(index, trial_sd=EMG_TRIAL_SD, repetition_sd=0.0, seed=seed) for seed in range(1500)
    ])
    # Without a repetition spread every sample of a trial carries the same factor per muscle.
    assert np.all(trials == trials[:, :1, :])
    log = np.log(trials[:, 0, :]).ravel()  # 12,000 draws
    assert abs(log.std(ddof=1) - EMG_TRIAL_SD) < 4 * EMG_TRIAL_SD / math.sqrt(2 * log.size)
    assert np.exp(log).mean() == pytest.approx(1.0, abs=4 * EMG_TRIAL_SD / math.sqrt(log.size))
    # Muscles draw apart: their factors are uncorrelated.
    assert abs(np.corrcoef(np.log(trials[:, 0, 0]), np.log(trials[:, 0, 1]))[0, 1]) < 0.1


def test_the_sizes_change_no_other_draw_and_a_seed_repeats_its_factors() -> None:
    index = np.repeat(np.arange(10), 4)
    none = amplitude_factors(index, trial_sd=0.0, repetition_sd=0.0, seed=5)
    np.testing.assert_array_equal(none, 1.0)
    a = amplitude_factors(index, trial_sd=0.1, repetition_sd=0.3, seed=5)
    b = amplitude_factors(index, trial_sd=0.2, repetition_sd=0.6, seed=5)
    # Same normals, twice the SD: log(b) + 0.5·(2s)² = 2·(log(a) + 0.5·s²) per component.
    np.testing.assert_allclose(np.log(b) + 0.5 * (0.2**2 + 0.6**2), 2 * (np.log(a) + 0.5 * (0.1**2 + 0.3**2)))
    np.testing.assert_array_equal(a, amplitude_factors(index, trial_sd=0.1, repetition_sd=0.3, seed=5))
    with pytest.raises(ParameterError, match="amplitude SDs"):
        amplitude_factors(index, trial_sd=-0.1, repetition_sd=0.3, seed=5)


def test_synthesized_semg_rms_scales_with_the_factor() -> None:
    # Constant activation 0.4, factors 0.5 / 1 / 2 over three 4 s segments: the sEMG's RMS in each
    # segment is 0.4 · factor · 0.5 mV (the carrier has unit RMS) plus 3 µV amplifier noise.
    t = np.arange(0.0, 12.0, 0.002)
    act = np.full((t.size, len(MUSCLES)), 0.4)
    segment_factor = np.array([0.5, 1.0, 2.0])[np.minimum((t // 4.0).astype(int), 2)]
    factors = np.tile(segment_factor[:, None], (1, len(MUSCLES)))
    frame = emg_synthesize(t, act, gains=(1.0,) * 8, heart_rate_bpm=60.0, ecg_amplitude=0.0, seed=4,
                           factors=factors)
    time = frame["time_s"].to_numpy()
    for s, factor in enumerate((0.5, 1.0, 2.0)):
        inner = (time > 4.0 * s + 0.3) & (time < 4.0 * (s + 1) - 0.3)
        rms = np.sqrt(np.mean(frame.loc[inner, "anterior_deltoid"].to_numpy() ** 2))
        assert rms == pytest.approx(math.hypot(0.4 * factor * 0.5e-3, 3e-6), rel=0.05)
    with pytest.raises(ParameterError, match="shape"):
        emg_synthesize(t, act, gains=(1.0,) * 8, heart_rate_bpm=60.0, ecg_amplitude=0.0, seed=4,
                       factors=factors[:-1])


@pytest.fixture(scope="module")
def two_trials():
    """One participant's trial with and without the amplitude spreads (the same motion: the factors
    draw from a stream of their own)."""
    base = generate_cohort(0, n_participants=2)[0]
    model = CompensationModel.from_friction(k=0.1)
    settings = ProtocolSettings(repetitions=6, speeds=("V3",))

    def trial(**fields: float):
        who = dataclasses.replace(base, **fields)
        return simulate_trial(who, "no_suit", "V3", model=model, settings=settings, seed=8)

    return trial(emg_trial_sd=0.0, emg_repetition_sd=0.0), trial(emg_trial_sd=0.1, emg_repetition_sd=0.63)


def test_a_trials_semg_and_its_activation_iemg_carry_the_drawn_factors(two_trials) -> None:
    varied = two_trials[1]
    factors = varied.emg_amplitude_factors()
    rep = varied.repetition_index()
    # The activation read-out (sim/calibration.py): each repetition's mean envelope is the plain
    # one times that repetition's factor, where the signal stands well above the amplifier's 3 µV
    # floor (added in quadrature): the agonists of raising, not the near-silent extensors.
    rows = [pd.DataFrame(activation_iemg_rows(t)) for t in two_trials]
    ratio = (rows[1]["mean"] / rows[0]["mean"]).to_numpy().reshape(5, 2, len(MUSCLES))
    expected = np.array([factors[rep == r][0] for r in range(1, 6)])
    agonists = [MUSCLES.index(m) for m in ("anterior_deltoid", "medial_deltoid", "trapezius")]
    np.testing.assert_allclose(ratio[:, 0, agonists], expected[:, agonists], rtol=0.02)
    assert np.all(np.abs(np.log(ratio[:, 0, :] / expected)) < 0.15)  # the floor only pulls toward 1
    # The synthesized sEMG: the same carrier, so its RMS over a repetition scales by the factor.
    emg = [t.emg() for t in two_trials]
    time = emg[0]["time_s"].to_numpy()
    cycle = np.interp(time, varied.time_s, rep.astype(float), left=-1, right=-1)
    for r in range(1, 6):
        inside = cycle == r
        for m, muscle in enumerate(("anterior_deltoid", "trapezius")):
            rms = [np.sqrt(np.mean(e.loc[inside, muscle].to_numpy() ** 2)) for e in emg]
            assert rms[1] / rms[0] == pytest.approx(expected[r - 1, MUSCLES.index(muscle)], rel=0.03), (r, m)


def test_the_cohort_carries_the_spreads_and_they_draw_nothing() -> None:
    default = generate_cohort(4)
    assert {(p.emg_trial_sd, p.emg_repetition_sd) for p in default} == {(EMG_TRIAL_SD, EMG_REPETITION_SD)}
    quiet = generate_cohort(4, emg_trial_sd=0.0, emg_repetition_sd=0.0)
    assert [dataclasses.replace(p, emg_trial_sd=0.0, emg_repetition_sd=0.0) for p in default] == list(quiet)
    with pytest.raises(ParameterError, match="emg_repetition_sd"):
        dataclasses.replace(default[0], emg_repetition_sd=1.5)


def test_the_implied_dispersion_inverts_the_condition_f_test() -> None:
    # Four conditions at log means 0, 0, +0.1, −0.1: Σ(η − η̄)² = 0.02, so with 459 repetitions each
    # the between-condition mean square is 459·0.02/3 = 3.06; at φ = 0.5 the F is 6.12 and its p on
    # (3, 1824) df is what the inversion must turn back into 0.5.
    p = float(stats.f.sf(6.12, 3, 1824))
    assert implied_dispersion([0.0, 0.0, 0.1, -0.1], p, n_per_condition=459, residual_df=1824) == (
        pytest.approx(0.5, rel=1e-9))
    # The paper's three condition tests the repetition spread was set by (Table S7) imply φ ≈ 0.45-0.47,
    # and a mean-one log-normal factor of SD 0.63 gives exp(0.63²) − 1 = 0.49 of it.
    script = load_module("emg_dispersion", Path(__file__).parents[2] / "scripts" / "emg_dispersion.py")
    implied = [script.paper_dispersion("entire", m) for m in ("posterior_deltoid", "biceps", "triceps")]
    assert implied == pytest.approx([0.456, 0.449, 0.467], abs=0.002)
    assert math.expm1(EMG_REPETITION_SD**2) == pytest.approx(np.mean(implied), abs=0.05)
    assert math.isnan(script.paper_dispersion("entire", "anterior_deltoid"))  # p printed "< 0.001"
    with pytest.raises(ValueError, match="p must be"):
        implied_dispersion([0.0, 0.1], 1.0, n_per_condition=10, residual_df=10)
