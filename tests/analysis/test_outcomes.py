"""analyse_study on synthetic trials whose outcome values are known by construction."""

import math

import numpy as np
import pandas as pd
import pytest

from bowden.analysis import AnalysisParameters, TrialMetadata, analyse_study, methods_text, sparc
from bowden.analysis.emg.process import EmgProcessParameters
from bowden.contracts import (
    MUSCLES,
    SPEED_PEAK_DEG_S,
    TRIAL_COLUMNS,
    TRIAL_DESIRED_TENSION,
    TRIAL_ELEVATION,
    TRIAL_ELEVATION_VELOCITY,
    TRIAL_MOMENT_ARM,
    TRIAL_REFERENCE_ELEVATION,
    TRIAL_TENSION,
    TRIAL_TIME,
)
from bowden.errors import ParameterError, RecordingError
from bowden.protocol import MinimumJerkCycle

from .conftest import RATE_HZ, ecg_wave, emg_noise

CONTROL_HZ = 200.0
LEAD_S = 1.0


def _cycle(speed: str) -> MinimumJerkCycle:
    return MinimumJerkCycle(peak_speed_rad_s=math.radians(SPEED_PEAK_DEG_S[speed]))


def _tau(time: np.ndarray, cycle: MinimumJerkCycle) -> np.ndarray:
    return np.mod(time - LEAD_S, cycle.period_s) / cycle.period_s


def make_trial(
    speed: str,
    *,
    tension_gain: float = 0.1,
    bump: float = 0.4,
    elevation_offset_rad: float = 0.02,
    with_tension: bool = True,
) -> pd.DataFrame:
    """A trial whose errors are known: tension = desired·(1 + gain + bump·g(τ)), g peaking at τ = 0.62."""
    cycle = _cycle(speed)
    time = np.arange(0.0, 2 * LEAD_S + 10 * cycle.period_s, 1.0 / CONTROL_HZ)
    moving = (time >= LEAD_S) & (time <= LEAD_S + 10 * cycle.period_s)
    reference = np.where(moving, cycle.elevation_rad(time - LEAD_S), cycle.low_rad)
    velocity = np.where(moving, cycle.elevation_velocity_rad_s(time - LEAD_S), 0.0)
    desired = 20.0 + 10.0 * np.sin(reference)
    g = np.exp(-0.5 * ((_tau(time, cycle) - 0.62) / 0.01) ** 2)
    frame = pd.DataFrame({name: np.zeros(time.size) for name in TRIAL_COLUMNS})
    frame[TRIAL_TIME] = time
    frame[TRIAL_REFERENCE_ELEVATION] = reference
    frame[TRIAL_ELEVATION] = reference + elevation_offset_rad
    frame[TRIAL_ELEVATION_VELOCITY] = velocity
    frame[TRIAL_DESIRED_TENSION] = desired
    frame[TRIAL_MOMENT_ARM] = 0.05 + 0.05 * np.sin(reference)
    frame[TRIAL_TENSION] = desired * (1.0 + tension_gain + bump * g) if with_tension else np.nan
    return frame


def make_emg(speed: str, gains: dict[str, float], seed: int) -> pd.DataFrame:
    """8-muscle EMG at 2 kHz: noise x (gain · activation), activation peaking at the top of each cycle."""
    cycle = _cycle(speed)
    rng = np.random.default_rng(seed)
    n = int((2 * LEAD_S + 10 * cycle.period_s) * RATE_HZ)
    time = np.arange(n) / RATE_HZ
    activation = 0.2 + np.sin(np.pi * _tau(time, cycle)) ** 2
    columns = {TRIAL_TIME: time}
    for muscle in MUSCLES:
        columns[muscle] = 50e-6 * gains.get(muscle, 1.0) * activation * emg_noise(n, rng)
    ecg, _ = ecg_wave(n, rng, amplitude_v=0.5e-3)
    columns["pectoralis_major"] = columns["pectoralis_major"] + ecg
    return pd.DataFrame(columns)


def test_tracking_measures_equal_their_construction():
    meta = TrialMetadata(participant="P01", condition="support_50", speed="V2")
    trial = make_trial("V2")
    result = analyse_study([(meta, trial)])
    out = result.outcomes
    assert list(out.columns) == [
        "participant",
        "condition",
        "speed",
        "trial_id",
        "repetition",
        "phase",
        "measure",
        "value",
    ]
    assert set(out["trial_id"]) == {1}  # the trial's place in the study (no store ids given)
    assert sorted(out["repetition"].unique()) == list(range(2, 11))
    cycle = _cycle("V2")

    def value(measure, phase, rep=5):
        row = out[(out.measure == measure) & (out.phase == phase) & (out.repetition == rep)]
        assert len(row) == 1
        return float(row["value"].iloc[0])

    start = LEAD_S + 4 * cycle.period_s
    t = trial[TRIAL_TIME].to_numpy()
    for phase, (a, b) in {"entire": (0.0, 1.0), "raising": (0.0, 0.5), "lowering": (0.5, 1.0)}.items():
        mask = (t >= start + a * cycle.period_s - 1e-9) & (t <= start + b * cycle.period_s + 1e-9)
        error = (trial[TRIAL_TENSION] - trial[TRIAL_DESIRED_TENSION]).to_numpy()[mask]
        arm = trial[TRIAL_MOMENT_ARM].to_numpy()[mask]
        assert value("tension_rmse_n", phase) == pytest.approx(np.sqrt(np.mean(error**2)), rel=1e-3)
        assert value("torque_rmse_nm", phase) == pytest.approx(np.sqrt(np.mean((error * arm) ** 2)), rel=1e-3)
        pct = 100.0 * error / trial[TRIAL_DESIRED_TENSION].to_numpy()[mask]
        assert value("percent_error_rmse_pct", phase) == pytest.approx(np.sqrt(np.mean(pct**2)), rel=1e-3)
        assert value("elevation_rmse_rad", phase) == pytest.approx(0.02, rel=1e-9)
    # The bump of +40 % at 62 % of the cycle is the lowering peak; raising stays at the +10 % floor.
    assert value("peak_percent_error_pct", "lowering") == pytest.approx(50.0, abs=0.5)
    assert value("peak_percent_error_time_pct", "lowering") == pytest.approx(62.0, abs=0.2)
    assert value("peak_percent_error_pct", "raising") == pytest.approx(10.0, abs=1e-6)
    # SPARC of one raising movement = SPARC of a minimum-jerk bell sampled the same way.
    tau = (
        np.arange(0.0, cycle.movement_duration_s + 0.5 / CONTROL_HZ, 1.0 / CONTROL_HZ)
        / cycle.movement_duration_s
    )
    bell = 30.0 * tau**2 * (1.0 - tau) ** 2
    assert value("sparc", "raising") == pytest.approx(sparc(bell, CONTROL_HZ), abs=2e-3)
    assert value("sparc", "entire") < value("sparc", "raising")  # two bells are less smooth than one


def test_rmse_table_has_the_papers_layout():
    trials = []
    expected = {}
    for i, condition in enumerate(("pretension", "support_25", "support_50")):
        for j, speed in enumerate(("V1", "V2", "V3")):
            gain = 0.02 * (1 + i + 3 * j)
            trials.append(
                (
                    {"participant": "P01", "condition": condition, "speed": speed},
                    make_trial(speed, tension_gain=gain, bump=0.0),
                )
            )
            expected[(condition, speed)] = gain
    trials.append(
        ({"participant": "P01", "condition": "no_suit", "speed": "V1"}, make_trial("V1", with_tension=False))
    )
    result = analyse_study(trials)
    table = result.rmse_table("percent_error_rmse_pct")
    assert list(table.index) == ["pretension", "support_25", "support_50"]
    assert list(table.columns) == [
        (s, p) for s in ("V1", "V2", "V3") for p in ("entire", "raising", "lowering")
    ]
    for (condition, speed), gain in expected.items():
        assert table.loc[condition, (speed, "raising")] == pytest.approx(100.0 * gain, rel=1e-9)
    no_suit = result.outcomes[result.outcomes.condition == "no_suit"]
    assert set(no_suit.measure) == {"elevation_rmse_rad", "sparc"}  # no load cell, no tension measures


def test_emg_is_normalised_to_no_suit_and_iemg_follows_the_known_gain():
    params = AnalysisParameters(emg=EmgProcessParameters())
    gains = {"anterior_deltoid": 0.6, "posterior_deltoid": 1.3}
    trials = [
        (
            TrialMetadata(participant="P02", condition="no_suit", speed="V3"),
            make_trial("V3", with_tension=False),
            make_emg("V3", {}, seed=1),
        ),
        (
            TrialMetadata(participant="P02", condition="support_50", speed="V3"),
            make_trial("V3"),
            make_emg("V3", gains, seed=2),
        ),
    ]
    result = analyse_study(trials, params)
    out = result.outcomes
    iemg = out[out.measure.str.startswith("iemg_")].pivot_table(
        index=["measure", "phase"], columns="condition", values="value", aggfunc="mean"
    )
    for muscle in MUSCLES:
        for phase in ("entire", "raising", "lowering"):
            ratio = (
                iemg.loc[(f"iemg_{muscle}", phase), "support_50"]
                / iemg.loc[(f"iemg_{muscle}", phase), "no_suit"]
            )
            assert ratio == pytest.approx(gains.get(muscle, 1.0), rel=0.08), (muscle, phase)
    # Raising + lowering = entire, per repetition.
    one = out[(out.measure == "iemg_biceps") & (out.repetition == 4) & (out.condition == "no_suit")]
    by_phase = dict(zip(one.phase, one.value, strict=True))
    assert by_phase["raising"] + by_phase["lowering"] == pytest.approx(by_phase["entire"], rel=1e-12)
    # The no-suit envelope is normalised to its mean per-repetition peak: its mean curve peaks near 1.
    curves = result.curves
    assert set(curves.columns) == {
        "participant",
        "condition",
        "speed",
        "signal",
        "normalised_time",
        "mean",
        "sd",
        "n",
    }
    no_suit_emg = curves[(curves.signal == "emg_biceps") & (curves.condition == "no_suit")]
    assert 0.75 < no_suit_emg["mean"].max() <= 1.05
    reference = curves[(curves.signal == "reference_elevation_rad") & (curves.condition == "support_50")]
    # Repetitions start on control samples (5 ms apart), so the reference differs by < 1 sample.
    assert reference["sd"].max() < 0.01
    assert reference["n"].min() == 9
    cycle = _cycle("V3")
    assert reference["mean"].to_numpy() == pytest.approx(
        cycle.elevation_rad(reference["normalised_time"].to_numpy() * cycle.period_s), abs=3e-3
    )
    assert result.info.heart_rate_bpm["pectoralis_major"] == pytest.approx(72.0, rel=0.05)
    assert result.info.segmentation_sources == {"reference": 2}


def test_missing_no_suit_reference_leaves_iemg_out_with_a_note():
    trials = [
        (
            TrialMetadata(participant="P03", condition="support_25", speed="V3"),
            make_trial("V3"),
            make_emg("V3", {}, seed=3),
        )
    ]
    result = analyse_study(trials)
    assert not result.outcomes.measure.str.startswith("iemg_").any()
    assert "no no-suit EMG" in result.info.notes[0]


def test_bad_trials_are_named():
    trial = make_trial("V3").drop(columns=[TRIAL_MOMENT_ARM])
    with pytest.raises(RecordingError, match=r"participant P04, support_25, V3: .*moment_arm_m"):
        analyse_study([({"participant": "P04", "condition": "support_25", "speed": "V3"}, trial)])
    with pytest.raises(ParameterError, match="condition must be one of"):
        analyse_study([({"participant": "P04", "condition": "support 99", "speed": "V3"}, make_trial("V3"))])
    with pytest.raises(ParameterError, match="lacks 'speed'"):
        analyse_study([({"participant": "P04", "condition": "no_suit"}, make_trial("V3"))])


def test_methods_text_follows_the_parameters():
    text = methods_text(AnalysisParameters())
    paragraph = text.paragraph
    for phrase in (
        "order 3 between 20 and 400 Hz",
        "100 ms",
        "mean of the 40 surrounding beats",
        "R ± 55 ms",
        "−10…+10 samples",
        "first repetition",
        "1001 points",
        "SPARC",
    ):
        assert phrase in paragraph
    assert any("Petersen" in ref for ref in text.references)
    plain = methods_text(
        AnalysisParameters(emg=EmgProcessParameters(ecg_removal="none", envelope_window_s=0.05))
    )
    assert "50 ms" in plain.paragraph
    assert "cardiac" not in plain.paragraph
    assert not any("Petersen" in ref for ref in plain.references)
    assert plain.to_markdown().count("\n1. ") == 1


def test_results_do_not_depend_on_the_number_of_workers():
    trials = [
        (
            TrialMetadata(participant=participant, condition=condition, speed="V3"),
            make_trial("V3", tension_gain=0.05 * (i + 1), with_tension=condition != "no_suit"),
            make_emg("V3", {"anterior_deltoid": 0.5 + 0.2 * i}, seed=10 + i),
        )
        for i, (participant, condition) in enumerate(
            [("P05", "no_suit"), ("P05", "support_25"), ("P06", "no_suit"), ("P06", "support_50")]
        )
    ]
    serial = analyse_study(iter(trials), workers=1)
    # Two worker processes (each spawned, importing the analysis: the test's cost), two trials each.
    parallel = analyse_study(iter(trials), workers=2)
    pd.testing.assert_frame_equal(parallel.outcomes, serial.outcomes, check_exact=True)
    pd.testing.assert_frame_equal(parallel.curves, serial.curves, check_exact=True)
    assert parallel.info == serial.info
    with pytest.raises(ParameterError, match="workers"):
        analyse_study(trials, workers=0)


def test_analyse_trial_names_the_trial_and_returns_its_measures():
    from bowden.analysis import analyse_trial

    meta = TrialMetadata(participant="P07", condition="support_25", speed="V2")
    result = analyse_trial(meta, make_trial("V2"))
    assert result.segmentation_source == "reference"
    assert len(result.repetitions) == 9 and result.emg_curves is None
    assert {row[5] for row in result.rows} >= {"tension_rmse_n", "sparc", "elevation_rmse_rad"}
    with pytest.raises(RecordingError, match="participant P07, support_25, V2"):
        analyse_trial(meta, make_trial("V2").drop(columns=[TRIAL_TENSION]))
