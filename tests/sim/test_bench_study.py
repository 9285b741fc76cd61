"""The study-like bench segment and the recommendation rule it feeds (issue 28, item 3)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from bowden.identify import TransmissionIdentifier
from bowden.model import CompensationModel
from bowden.protocol.bench import QUICK_BENCH
from bowden.sim.bench import run_bench
from bowden.sim.bench_study import recommend_compensation, run_study_segment
from bowden.sim.parameters import SuitParameters


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
