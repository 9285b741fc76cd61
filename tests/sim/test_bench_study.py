"""The study-like bench segment and the recommendation rule it feeds (issue 28, item 3)."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from bowden.cli import main
from bowden.control import build_controller
from bowden.identify import TransmissionIdentifier
from bowden.identify.study_fit import StrokeResult, study_cost
from bowden.identify.study_recommendation import recommendation
from bowden.model import CompensationModel, Subject
from bowden.model.model_file import load_model
from bowden.protocol.bench import QUICK_BENCH
from bowden.sim import ProtocolSettings, generate_cohort, simulate_trial
from bowden.sim.bench import run_bench
from bowden.sim.bench_study import (
    fit_on_study_segment,
    recommend_compensation,
    run_study_segment,
    validate_compensations,
)
from bowden.sim.parameters import SuitParameters
from bowden.sim.plant_family_structural import random_structural_plants, structural_plants
from bowden.study.compensation.comparison import reference_tension, trial_errors


@pytest.fixture(scope="module")
def model() -> CompensationModel:
    return TransmissionIdentifier().fit(run_bench(SuitParameters(), QUICK_BENCH, seed=0)).model_


def test_the_identified_dynamic_compensation_is_recommended_where_it_beats_the_papers(
    model: CompensationModel,
) -> None:
    choice = recommend_compensation(model, SuitParameters())
    # Every support of the study at every speed, each cell judged on its own held-out strokes.
    assert {(support, speed) for support, speed, _ in choice.cells} == {
        (support, speed) for support in ("pretension", "25", "50") for speed in ("V1", "V2", "V3")}
    # At 50 % and the fastest speed the dynamic compensation's win is far outside the strokes' scatter
    # (at V2 the mannequin's motor noise makes an occasional stroke spike: not always with confidence).
    assert ("50", "V3", True) in choice.cells, choice.why


def _stroke(rmse_n: float, peak_pct: float, scatter: tuple[float, ...] = (-0.02, 0.0, 0.01, 0.02, -0.01, 0.0)
            ) -> StrokeResult:
    """A cell's result with six held-out strokes scattered about its values by the given fractions."""
    return StrokeResult(tension_rmse_n=rmse_n, onset_peak_pct=peak_pct,
                        stroke_rmse_n=tuple(rmse_n * (1 + f) for f in scatter),
                        stroke_peak_pct=tuple(peak_pct * (1 + f) for f in scatter))


def test_the_recommendation_is_per_support_and_speed_and_the_controller_follows_it(
    model: CompensationModel,
) -> None:
    # Dynamic wins everywhere but at pretension V3 (onset peak) and 25 % V1 (RMSE).
    results = {(support, speed): {"paper": _stroke(4.0, 40.0), "dynamic": _stroke(2.0, 20.0)}
               for support in ("pretension", "25", "50") for speed in ("V1", "V2", "V3")}
    results["pretension", "V3"]["dynamic"] = _stroke(2.0, 41.0)
    results["25", "V1"]["dynamic"] = _stroke(4.1, 20.0)
    choice = recommendation(results)
    assert not choice.everywhere
    assert [cell[:2] for cell in choice.cells if not cell[2]] == [("pretension", "V3"), ("25", "V1")]
    assert choice.why.startswith("dynamic in 7 of 9 cells (the 95 % upper bound")
    assert "pretension V3" in choice.why
    chosen = choice.apply(model)
    dynamic = chosen.dynamic
    assert dynamic is not None and dynamic.recommended_cells == choice.cells
    assert not dynamic.recommended_for("pretension", "V3") and dynamic.recommended_for("pretension", "V2")
    assert not dynamic.recommended_for(0.25, "V1") and dynamic.recommended_for(0.25, "V3")
    # Speed unknown: dynamic only where it won at every speed of that support; an unmeasured support:
    # only if it won every cell.
    assert dynamic.recommended_for(0.5, None) and not dynamic.recommended_for("pretension", None)
    assert not dynamic.recommended_for(0.4, "V2")

    def compensation(support: float | str, speed: str | None) -> str:
        controller = build_controller(model=chosen, support=support,  # type: ignore[arg-type]
                                      subject=Subject(height_m=1.7, mass_kg=63.0, sex="female"),
                                      speed=speed)
        return controller.compensation

    assert compensation("pretension", "V3") == "paper" and compensation("pretension", "V1") == "dynamic"
    assert compensation(0.25, "V1") == "paper" and compensation(0.5, None) == "dynamic"


def test_a_dynamic_compensation_that_loses_on_the_bench_is_not_recommended(model: CompensationModel) -> None:
    assert model.dynamic is not None
    # Ten times the identified drag: the command overshoots at every speed, most at the fastest.
    drag = 10 * model.dynamic.viscous_nm_s_rad
    wrong = replace(model, dynamic=replace(model.dynamic, viscous_nm_s_rad=drag))
    paper = run_study_segment(wrong, SuitParameters(), compensation="paper", speed="V3")
    dynamic = run_study_segment(wrong, SuitParameters(), compensation="dynamic", speed="V3")
    assert dynamic.tension_rmse_n > paper.tension_rmse_n
    choice = recommend_compensation(wrong, SuitParameters())
    assert not choice.everywhere
    assert ("50", "V3", False) in choice.cells  # the cell measured above
    assert "the paper's lines in: " in choice.why and "50 % V3 (RMSE ≤ " in choice.why


def test_bench_simulate_writes_the_latency_segment_and_validate_recommends(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bench, latency, model_path = tmp_path / "bench.csv", tmp_path / "latency.csv", tmp_path / "model.json"
    assert main(["bench", "simulate", "-o", str(bench), "--speeds", "0.5", "2", "6", "--loads", "1", "3",
                 "--repetitions", "1", "--quiet", "--latency-out", str(latency)]) == 0
    assert main(["identify", str(bench), "-o", str(model_path), "--latency-recording", str(latency)]) == 0
    dynamic = load_model(model_path).dynamic
    assert dynamic is not None and dynamic.imu_latency_s == pytest.approx(0.05, abs=0.003)
    capsys.readouterr()
    assert main(["bench", "validate", str(model_path), "-o", str(model_path)]) == 0
    out = capsys.readouterr().out
    for support in ("pretension", "25", "50"):
        assert re.search(rf"^{support}\s+V3\s+dynamic\s+\d+\.\d\d\s+-?\d+\.\d$", out, re.MULTILINE)
    recommended = r"^recommended: (dynamic in \d of 9 cells|the dynamic compensation beats)"
    assert re.search(recommended, out, re.MULTILINE)
    validated = load_model(model_path).dynamic
    assert validated is not None and len(validated.recommended_cells) == 9
    assert ("50", "V3", True) in validated.recommended_cells
    assert validated.recommendation in out
    assert main(["bench", "validate", str(model_path), "--support", "2"]) == 1
    assert "--support" in capsys.readouterr().err


def test_the_fit_on_study_strokes_lowers_their_cost_on_a_suit_with_presliding(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import bowden.identify.study_fit as study_fit

    monkeypatch.setattr(study_fit, "FIT_INERTIA_SCALES", (1.0,))  # a smaller grid: a faster test
    suit = next(plant.suit for plant in structural_plants() if plant.name == "dahl")
    identified = TransmissionIdentifier().fit(run_bench(suit, QUICK_BENCH, seed=0)).model_
    fitted = fit_on_study_segment(identified, suit, seed=0)
    assert fitted.dynamic is not None and identified.dynamic is not None
    assert fitted.raising == identified.raising and fitted.lowering == identified.lowering  # the paper's
    # Judged on strokes held out of the fit (other seed): the fitted model costs less.
    before = study_cost(validate_compensations(identified, suit, seed=1))
    after = study_cost(validate_compensations(fitted, suit, seed=1))
    assert after < before


def test_the_mannequin_yields_like_a_wearer_so_the_bench_shows_the_cohorts_errors() -> None:
    # structural-28-1 (presliding, capstan, play, high drag): with the mannequin stiff (300 Nm/rad) the
    # paper's onset peak at pretension/V3 on the bench was 1.5 times the cohort's, and the bench ranked
    # the two compensations otherwise than the cohort did in that cell.
    suit = random_structural_plants(6, 28)[1].suit
    model = TransmissionIdentifier().fit(run_bench(suit, QUICK_BENCH, seed=0)).model_
    settings = ProtocolSettings(conditions=("pretension",), speeds=("V3",), repetitions=5,
                                compensation="paper")
    cohort = [trial_errors(trial, reference_tension(trial, settings, suit.geometry)) for trial in (
        simulate_trial(participant, "pretension", "V3", model=model, suit=suit, settings=settings, seed=index)
        for index, participant in enumerate(generate_cohort(0)[:6]))]
    bench = run_study_segment(model, suit, compensation="paper", speed="V3", support="pretension")
    peak = bench.onset_peak_pct / np.mean([errors["onset_peak_pct"] for errors in cohort])
    rmse = bench.tension_rmse_n / np.mean([errors["tension_rmse_n"] for errors in cohort])
    assert 0.8 < peak < 1.2 and 0.8 < rmse < 1.2, (peak, rmse)


def test_the_mannequin_moves_with_a_wearers_motor_noise_so_the_slow_turn_is_the_cohorts(
    model: CompensationModel,
) -> None:
    # At 60 °/s a noise-free mannequin's arm crept through the top turn, held back by the stuck cable,
    # inside the dynamic compensation's reversal hysteresis for 330-470 ms: on the bench its onset
    # spike was 1.7 times the paper's at pretension where with the cohort, whose arms move with motor
    # noise, it is a third of the paper's. With a wearer's motor noise the bench ranks them as the
    # cohort does.
    suit = SuitParameters()
    peaks = {}
    for compensation in ("paper", "dynamic"):
        settings = ProtocolSettings(conditions=("pretension",), speeds=("V1",), repetitions=5,
                                    compensation=compensation)
        cohort = [trial_errors(trial, reference_tension(trial, settings, suit.geometry)) for trial in (
            simulate_trial(participant, "pretension", "V1", model=model, suit=suit, settings=settings,
                           seed=index)
            for index, participant in enumerate(generate_cohort(0)[:3]))]
        bench = run_study_segment(model, suit, compensation=compensation, speed="V1", support="pretension",
                                  repetitions=7, seed=1)
        peaks[compensation] = (np.mean([errors["onset_peak_pct"] for errors in cohort]), bench.onset_peak_pct)
    cohort_ratio = peaks["dynamic"][0] / peaks["paper"][0]
    bench_ratio = peaks["dynamic"][1] / peaks["paper"][1]
    assert cohort_ratio < 0.5 and bench_ratio < 0.8, (cohort_ratio, bench_ratio)
