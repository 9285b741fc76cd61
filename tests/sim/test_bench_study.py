"""The study-like bench segment and the recommendation rule it feeds (issue 28, item 3)."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import pytest

from bowden.cli import main
from bowden.identify import TransmissionIdentifier
from bowden.model import CompensationModel
from bowden.model.model_file import load_model
from bowden.protocol.bench import QUICK_BENCH
from bowden.sim.bench import run_bench
from bowden.sim.bench_study import (
    fit_on_study_segment,
    recommend_compensation,
    run_study_segment,
    study_cost,
    validate_compensations,
)
from bowden.sim.parameters import SuitParameters
from bowden.sim.plant_family_structural import structural_plants


@pytest.fixture(scope="module")
def model() -> CompensationModel:
    return TransmissionIdentifier().fit(run_bench(SuitParameters(), QUICK_BENCH, seed=0)).model_


def test_the_identified_dynamic_compensation_is_recommended_where_it_beats_the_papers(
    model: CompensationModel,
) -> None:
    choice, why = recommend_compensation(model, SuitParameters())
    assert choice == "dynamic", why


def test_a_dynamic_compensation_that_loses_on_the_bench_is_not_recommended(model: CompensationModel) -> None:
    assert model.dynamic is not None
    # Ten times the identified drag: the command overshoots at every speed, most at the fastest.
    drag = 10 * model.dynamic.viscous_nm_s_rad
    wrong = replace(model, dynamic=replace(model.dynamic, viscous_nm_s_rad=drag))
    paper = run_study_segment(wrong, SuitParameters(), compensation="paper", speed="V3")
    dynamic = run_study_segment(wrong, SuitParameters(), compensation="dynamic", speed="V3")
    assert dynamic.tension_rmse_n > paper.tension_rmse_n
    choice, why = recommend_compensation(wrong, SuitParameters())
    assert choice == "paper"
    assert "does not beat the paper's" in why


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
    assert re.search(r"^V3\s+dynamic\s+\d+\.\d\d\s+-?\d+\.\d$", out, re.MULTILINE)
    assert "recommended: dynamic" in out
    validated = load_model(model_path).dynamic
    assert validated is not None and validated.recommended
    assert validated.recommendation.startswith("the dynamic compensation beats the paper's")
    assert main(["bench", "validate", str(model_path), "--support", "2"]) == 1
    assert "--support" in capsys.readouterr().err


def test_the_fit_on_study_strokes_lowers_their_cost_on_a_suit_with_presliding(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import bowden.sim.bench_study as bench_study

    monkeypatch.setattr(bench_study, "FIT_INERTIA_SCALES", (1.0,))  # a smaller grid: a faster test
    suit = next(plant.suit for plant in structural_plants() if plant.name == "dahl")
    identified = TransmissionIdentifier().fit(run_bench(suit, QUICK_BENCH, seed=0)).model_
    fitted = fit_on_study_segment(identified, suit, seed=0)
    assert fitted.dynamic is not None and identified.dynamic is not None
    assert fitted.raising == identified.raising and fitted.lowering == identified.lowering  # the paper's
    # Judged on strokes held out of the fit (other seed): the fitted model costs less.
    before = study_cost(validate_compensations(identified, suit, seed=1))
    after = study_cost(validate_compensations(fitted, suit, seed=1))
    assert after < before
