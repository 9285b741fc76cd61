"""The identification estimator on recordings generated from the transmission law (truth by hand)."""

from __future__ import annotations

import hashlib
import math
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from bowden import __version__
from bowden.contracts import BENCH_MOTOR_TORQUE, BENCH_MOTOR_VELOCITY, BENCH_TENSION
from bowden.errors import FitError, ParameterError, RecordingError
from bowden.identify import PreprocessSettings, TransmissionIdentifier, robustfit
from bowden.model.model_file import load_model, save_model
from bowden.model.transmission import slopes_from_friction

from .law_bench import LawTruth, law_bench_frame


def test_noise_free_law_recording_recovers_the_truth() -> None:
    truth = LawTruth()
    # Hand-derived: R(1+k)/(1-k) = 0.035·1.1/0.9 and R(1-k)/(1+k) = 0.035·0.9/1.1.
    assert truth.slope_raising_m == pytest.approx(0.0427777778)
    assert truth.slope_lowering_m == pytest.approx(0.0286363636)
    identifier = TransmissionIdentifier().fit(law_bench_frame(truth=truth))
    model = identifier.model_
    assert model.raising.slope_m == pytest.approx(truth.slope_raising_m, rel=1e-5)
    assert model.lowering.slope_m == pytest.approx(truth.slope_lowering_m, rel=1e-5)
    assert model.raising.intercept_nm == pytest.approx(truth.intercept_raising_nm, abs=1e-5)
    assert model.lowering.intercept_nm == pytest.approx(truth.intercept_lowering_nm, abs=1e-5)
    assert identifier.summary_.k == pytest.approx(truth.k, rel=1e-4)
    assert identifier.summary_.consistent_with_one_k


def test_noisy_recording_with_outliers_stays_within_one_percent() -> None:
    truth = LawTruth(k=0.15, intercept_raising_nm=0.1, intercept_lowering_nm=0.0)
    frame = law_bench_frame(
        truth=truth, noise_tension_n=0.8, noise_torque_nm=0.02, outlier_fraction=0.002, seed=4
    )
    identifier = TransmissionIdentifier().fit(frame)
    assert identifier.model_.raising.slope_m == pytest.approx(truth.slope_raising_m, rel=0.01)
    assert identifier.model_.lowering.slope_m == pytest.approx(truth.slope_lowering_m, rel=0.01)
    for fit in (identifier.model_.raising_fit, identifier.model_.lowering_fit):
        assert fit is not None
        assert fit.r_squared_robust >= 0.99 and fit.r_squared_ols >= 0.99
    assert identifier.summary_.consistent_with_one_k
    assert identifier.summary_.warnings == ()


def test_model_carries_fit_statistics_equal_to_robustfit_on_the_selection() -> None:
    identifier = TransmissionIdentifier().fit(law_bench_frame(noise_tension_n=0.3, noise_torque_nm=0.01))
    selection = identifier.selection_
    direct = robustfit(selection.tension_n("lowering"), selection.motor_torque_nm("lowering"))
    stats = identifier.model_.lowering_fit
    assert stats is not None
    assert identifier.model_.lowering.slope_m == direct.slope
    assert stats.n == direct.n == selection.count("lowering")
    assert stats.r_squared_robust == direct.r_squared_fitlm_robust
    assert stats.r_squared_ols == direct.r_squared_ols
    assert stats.robust_scale_nm == direct.scale
    assert stats.slope_se_m == direct.slope_se and stats.intercept_se_nm == direct.intercept_se


def test_provenance_and_round_trip_through_model_json(tmp_path: Path) -> None:
    paths = []
    for index, seed in enumerate((1, 2)):
        path = tmp_path / f"bench{index}.csv"
        law_bench_frame(noise_torque_nm=0.01, seed=seed).to_csv(path, index=False)
        paths.append(path)
    identifier = TransmissionIdentifier(blend_velocity_01_rad_s=-0.5, blend_velocity_99_rad_s=0.5).fit(paths)
    provenance = identifier.model_.provenance
    assert provenance is not None
    assert provenance.source_files == tuple(str(p) for p in paths)
    assert provenance.source_sha256 == tuple(hashlib.sha256(p.read_bytes()).hexdigest() for p in paths)
    assert provenance.tool == "bowden identify" and provenance.tool_version == __version__
    created = datetime.fromisoformat(provenance.created_utc)
    assert created.tzinfo is not None and created.utcoffset() == UTC.utcoffset(None)
    assert abs((datetime.now(UTC) - created).total_seconds()) < 600
    assert "5 Hz" in provenance.notes and "15 °/s" in provenance.notes
    target = tmp_path / "model.json"
    save_model(identifier.model_, target)
    loaded = load_model(target)
    assert loaded == identifier.model_
    assert loaded.blend_weight(0.5) == pytest.approx(0.99)


def test_predict_blends_the_lines_by_elevation_velocity() -> None:
    identifier = TransmissionIdentifier().fit(law_bench_frame())
    model = identifier.model_
    torque = identifier.predict([20.0, 20.0, 20.0], [-3.0, 0.0, 3.0])
    assert torque[0] == pytest.approx(model.lowering.torque_nm(20.0), rel=1e-3)
    assert torque[2] == pytest.approx(model.raising.torque_nm(20.0), rel=1e-3)
    assert torque[1] == pytest.approx(0.5 * (model.lowering.torque_nm(20.0) + model.raising.torque_nm(20.0)))
    with pytest.raises(FitError, match="not fitted"):
        TransmissionIdentifier().predict(1.0, 1.0)


def test_too_few_samples_in_a_direction_names_it_and_the_criteria() -> None:
    frame = law_bench_frame(spool_speeds_rad_s=(1.0,), loads_nm=(2.0,))
    # Drop nearly all lowering: keep only the first 20 samples of negative spool velocity.
    lowering = np.flatnonzero(frame[BENCH_MOTOR_VELOCITY].to_numpy() < 0)
    frame = frame.drop(index=frame.index[lowering[20:]]).reset_index(drop=True)
    with pytest.raises(RecordingError) as info:
        TransmissionIdentifier().fit(frame)
    message = str(info.value)
    assert "too few steady-state samples while lowering" in message
    assert "(need at least 50)" in message
    assert "fail |spool acceleration| < 15 °/s²" in message


def test_swapped_velocity_sign_is_a_fit_error() -> None:
    # The raising line would come out below the lowering one, which no friction gives and which
    # model.json refuses to load: say why instead of writing it.
    frame = law_bench_frame()
    frame[BENCH_MOTOR_VELOCITY] *= -1.0  # a motor mounted the other way round
    with pytest.raises(FitError, match="check the sign of motor_velocity_rad_s"):
        TransmissionIdentifier().fit(frame)


def test_implausible_slope_is_a_fit_error() -> None:
    frame = law_bench_frame()
    frame[BENCH_MOTOR_TORQUE] *= -1.0  # torque sign flipped: negative slope
    settings = PreprocessSettings(min_torque_nm=-100.0)
    with pytest.raises(FitError, match=r"the raising line has slope -0\.04"):
        TransmissionIdentifier(preprocessing=settings).fit(frame)


@pytest.mark.parametrize(
    ("column", "factor", "hint"),
    [
        (BENCH_TENSION, 1 / 9.80665, "kilogram-force"),  # the load cell read in kgf
        (BENCH_TENSION, 1 / 4.44822, "pound-force"),
        (BENCH_MOTOR_TORQUE, 1 / 9.80665, "kgf·m"),
        (BENCH_MOTOR_TORQUE, 3.0, "check the units"),  # no known unit: the generic hint
    ],
)
def test_lines_a_pulley_cannot_give_are_a_unit_error(column: str, factor: float, hint: str) -> None:
    # sqrt(m_raise·m_lower) is R/c whatever the friction (supplement, eq. S5); beyond a factor 2 it is units.
    frame = law_bench_frame()
    frame[column] *= factor
    with pytest.raises(FitError, match=hint):
        TransmissionIdentifier(preprocessing=PreprocessSettings(min_torque_nm=0.0)).fit(frame)


def test_torque_constant_error_breaks_the_single_k_check() -> None:
    # A torque constant 15 % high (CubeMars data: ±15 %) scales both slopes: k is unchanged, the geometric
    # mean of the slopes moves 15 % away from the pulley radius.
    frame = law_bench_frame()
    frame[BENCH_MOTOR_TORQUE] *= 1.15
    summary = TransmissionIdentifier().fit(frame).summary_
    assert summary.k == pytest.approx(0.1, rel=1e-4)
    assert summary.radius_deviation == pytest.approx(0.15, abs=1e-4)
    assert not summary.consistent_with_one_k
    assert any("do not fit one friction factor" in w for w in summary.warnings)


def test_parameters_are_validated_and_settable() -> None:
    with pytest.raises(ParameterError, match="pulley_radius_m"):
        TransmissionIdentifier(pulley_radius_m=35.0)
    with pytest.raises(ParameterError, match="min_samples_per_direction"):
        TransmissionIdentifier(min_samples_per_direction=1)
    with pytest.raises(ParameterError, match="blend_velocity_99_rad_s"):
        TransmissionIdentifier(blend_velocity_01_rad_s=1.0, blend_velocity_99_rad_s=-1.0)
    identifier = TransmissionIdentifier()
    assert identifier.set_params(pulley_radius_m=0.04) is identifier
    assert identifier.get_params()["pulley_radius_m"] == 0.04
    assert repr(identifier) == "TransmissionIdentifier(pulley_radius_m=0.04)"
    with pytest.raises(ParameterError, match="unknown parameter"):
        identifier.set_params(radius=0.04)


def test_ideal_model_from_friction_matches_identified_one() -> None:
    # The lead's ideal law and this tool agree on what k = 0.1 means.
    raising, lowering = slopes_from_friction(0.1, 0.035)
    identified = TransmissionIdentifier().fit(law_bench_frame()).model_
    assert identified.raising.slope_m == pytest.approx(raising, rel=1e-5)
    assert identified.lowering.slope_m == pytest.approx(lowering, rel=1e-5)
    assert math.isclose(identified.pulley_radius_m, 0.035)
