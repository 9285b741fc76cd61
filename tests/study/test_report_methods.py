"""Issue 29, item 5: the report's Methods paragraph is complete and true to the data."""

from __future__ import annotations

import html
import re

from bowden.analysis import AnalysisParameters, methods_text
from bowden.analysis.outcomes import AnalysisInfo
from bowden.analysis.segmentation import SegmentationParameters
from bowden.model import CompensationModel
from bowden.model.lines import CompensationLine, LineFitStats
from bowden.study.report.build import build_report, complete_methods

from .report_inputs import report_inputs


def _identified() -> CompensationModel:
    fit = LineFitStats(n=1234, r_squared_ols=0.99, r_squared_robust=0.9987, robust_scale_nm=0.01,
                       intercept_se_nm=1e-4, slope_se_m=1e-6)
    return CompensationModel(
        raising=CompensationLine(intercept_nm=0.111, slope_m=0.04276),
        lowering=CompensationLine(intercept_nm=-0.107, slope_m=0.02863),
        raising_fit=fit, lowering_fit=fit,
    )


def _methods_of(body: str) -> str:
    start = body.index(">Methods</h2>")
    return html.unescape(re.search(r"<p>(.*?)</p>", body[start:], re.S).group(1))  # type: ignore[union-attr]


def test_the_methods_describe_the_statistics_as_fitted() -> None:
    inputs = report_inputs(model=_identified())
    text = _methods_of("\n".join(build_report(inputs).parts))
    for phrase in (
        "gamma distribution and log link", "random intercept per participant", "Type III Wald F tests",
        "Holm's correction", "Friedman's test", "Bonferroni correction", "pseudo-likelihood with REML",
        "Elevation RMSE, SPARC and the iEMG of each of 8 muscles (entire cycle, raising, lowering)",
        # what the questionnaires gave: two items tested, Borg RPE's compared pairwise
        "Questionnaire answers (2 items)", "for the 1 item with p < 0.05",
    ):
        assert phrase in text, phrase
    references = complete_methods(inputs).references
    assert any(ref.startswith("Holm S. (1979)") for ref in references)
    assert any(ref.startswith("Friedman M. (1937)") for ref in references)
    # Citations are numbered on from the analysis' own, once each.
    numbers = [int(n) for n in re.findall(r"\[(\d+)\]", text)]
    assert sorted(set(numbers)) == list(range(1, len(references) + 1))


def test_the_methods_give_the_identified_lines() -> None:
    text = complete_methods(report_inputs(model=_identified())).paragraph
    assert "robust line (bisquare weights" in text
    assert "raising, torque = 0.111 Nm + 42.76 mm × tension (n = 1234 samples, robust R² = 0.9987)" in text
    assert "lowering, torque = -0.107 Nm + 28.63 mm × tension" in text
    assert "1 % weight at -1 rad/s and 99 % at +1 rad/s" in text
    # A model given without identification statistics is not said to have been identified.
    given = complete_methods(report_inputs(model=CompensationModel.from_friction(k=0.1))).paragraph
    assert "identified on the bench" not in given and "holds no identification statistics" in given
    assert "transmission" not in complete_methods(report_inputs(model=None)).paragraph.lower()


def test_one_participant_in_the_singular_and_no_exclusion_unless_it_happened() -> None:
    one = complete_methods(report_inputs(n_participants=1, n_repetitions=1, drop_first=0)).paragraph
    assert one.startswith("Data of 1 participant (12 trials, 12 repetitions) were analysed.")
    assert "of each trial was excluded" not in one and "after exclusions" not in one
    many = complete_methods(report_inputs(n_participants=2, n_repetitions=3, drop_first=1)).paragraph
    assert many.startswith("Data of 2 participants (24 trials, 72 repetitions) were analysed.")
    assert "The first repetition of each trial was excluded to avoid adaptation effects" in many


def test_the_segmentation_source_is_what_the_trials_were_segmented_on() -> None:
    def text(sources: dict[str, int]) -> str:
        info = AnalysisInfo(parameters=AnalysisParameters(segmentation=SegmentationParameters(drop_first=0)),
                            n_trials=sum(sources.values()), n_participants=1, n_repetitions=12,
                            segmentation_sources=sources, notes=(), heart_rate_bpm={})
        return methods_text(info=info).paragraph

    assert "segmented on the reference trajectory and split" in text({"reference": 12})
    assert "segmented on the measured elevation and split" in text({"elevation": 12})
    assert ("segmented on the reference trajectory (10 trials) or, where no reference was recorded, the "
            "measured elevation (1 trial)") in text({"reference": 10, "elevation": 1})
