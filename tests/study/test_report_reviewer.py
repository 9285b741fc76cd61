"""Issue 29, items 4 and 6: a report a reviewer can read.

The report is built from drawn outcome tables (tests/study/report_inputs.py) with statistics fitted
for real, so each test sees the shapes a study gives without simulating one. Fitting them takes about
2 s of CPU, building the report's body about 1.5 s and drawing its figures about 7 s, so one
four-participant study (a bench, questionnaires, notes to condense) is made once, its body and its whole
report too (module fixtures); the study without a bench or questionnaires is derived from its inputs,
refitting nothing.
"""

from __future__ import annotations

import dataclasses
import html
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.colors import to_hex

from bowden.contracts import CONDITIONS
from bowden.model import CompensationModel
from bowden.study.report.build import ReportInputs, build_report
from bowden.study.report.figures import CONDITION_COLOURS, participant_curves
from bowden.study.statistics import questionnaire_tests

from .report_inputs import curves, report_inputs

# The analysis's notes: EMG sources of 204 trials, skipped trials with one reason, a trial set aside.
NOTES = (
    "EMG of trials " + ", ".join(str(i) for i in range(1, 205)) + ": recorded with the trial",
    *(f"trial {i} (participant P0{i % 3 + 1}, no_suit, V1) skipped: it holds no samples"
      for i in (300, 301, 302, 305)),
    "trial 400 (participant P01, support_50, V2) set aside: the suit stalled",
)


@dataclass(frozen=True)
class Study:
    """A four-participant study with a bench, questionnaires and :data:`NOTES`: its inputs, its body, its
    whole report."""

    inputs: ReportInputs
    body: str  # what _body gives
    report: str  # rendered: the contents added, figures drawn


@pytest.fixture(scope="module")
def study() -> Study:
    inputs = report_inputs(model=CompensationModel.from_friction(k=0.1), notes=NOTES)
    document = build_report(inputs)
    body = "\n".join(document.parts)  # before render() puts the drawn figures in its parts
    return Study(inputs=inputs, body=body, report=document.render())


@pytest.fixture(scope="module")
def report(study: Study) -> str:
    """The whole report of a four-participant study, figures drawn."""
    return study.report


def _body(inputs: ReportInputs) -> str:
    """The report's HTML without drawing its figures."""
    return "\n".join(build_report(inputs).parts)


def _without_bench_or_answers(inputs: ReportInputs) -> ReportInputs:
    """``inputs`` as ``report_inputs(model=None, with_answers=False)`` gives them (same notes): the
    outcomes' fits do not depend on the answers, and the questionnaires' tests are those of no answers."""
    tests, posthoc = questionnaire_tests(pd.DataFrame())
    statistics = dataclasses.replace(inputs.statistics, questionnaires=tests, questionnaire_posthoc=posthoc)
    return dataclasses.replace(inputs, model=None, questionnaires=pd.DataFrame(), statistics=statistics)


def _cells(text: str) -> list[str]:
    return [html.unescape(cell) for cell in re.findall(r"<td[^>]*>([^<]*)</td>", text)]


def test_the_contents_link_every_section_heading_in_order(report: str) -> None:
    nav = re.search(r'<nav class="toc">(.*?)</nav>', report, re.S)
    assert nav is not None
    targets = re.findall(r'<a href="#([^"]+)">([^<]*)</a>', nav.group(1))
    headings = re.findall(r'<h([23]) id="([^"]+)">([^<]*)</h\1>', report)
    assert [(anchor, text) for anchor, text in targets] == [(anchor, text) for _, anchor, text in headings]
    ids = re.findall(r'\bid="([^"]+)"', report)
    assert len(ids) == len(set(ids))  # every link has one target
    assert {"methods", "questionnaires", "muscle-activity-iemg"} <= {anchor for anchor, _ in targets}
    assert report.index("<nav") < report.index("<h2")


def test_p_values_are_printed_one_way_everywhere(report: str) -> None:
    # The elevation RMSE's condition effect has p ~ 1e-88; printed as the statistics give it, it read
    # 1.28e-88 in the departures table, next to "< 0.001" in the GLMM table.
    text = re.sub(r'src="data:[^"]*"', "", report)
    assert not re.findall(r"\b\d(?:\.\d+)?e[-+]?\d+\b", text)
    assert "&lt; 0.001" in report
    p_cells = re.findall(r"<td[^>]*>(\d\.\d+)</td>", report)
    assert p_cells  # numbers remain numbers


def test_pairwise_cells_left_out_say_why(report: str) -> None:
    not_compared = [cell for cell in _cells(report) if cell.startswith("N/A")]
    assert not_compared  # SPARC has no condition effect
    assert all(re.fullmatch(r"N/A \(p \((C|V)\) = (\d\.\d{3}|< 0\.001)\)", cell) for cell in not_compared)
    assert "SPARC (-)" in report and "N/A (p (C) = 0." in html.unescape(report)
    assert "not compared, as in the paper" in report


def test_a_p_value_never_wraps(report: str) -> None:
    # Numbers never break over lines (a wide table scrolls in its box); running text still wraps.
    style = re.search(r"<style>(.*?)</style>", report, re.S)
    assert style is not None and re.search(r"\btd\s*\{[^}]*white-space:\s*nowrap", style.group(1))
    assert re.search(r"td\.text\s*\{[^}]*white-space:\s*normal", style.group(1))
    assert not re.search(r'<td class="text">[^<]*0\.001', report)


def test_a_p_value_fits_on_one_line_in_chromium(report: str, tmp_path: Path) -> None:
    sync_api = pytest.importorskip("playwright.sync_api")
    from .report_layout import CHROMIUM, VIEWPORT

    if not CHROMIUM.exists():
        pytest.skip("Debian's chromium is not installed")
    path = tmp_path / "report.html"
    path.write_text(report, encoding="utf-8")
    lines = """() => [...document.querySelectorAll('td')].filter(td => td.textContent.includes('0.001'))
        .map(td => { const range = document.createRange(); range.selectNodeContents(td);
                     return [td.textContent, range.getClientRects().length]; })"""
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=str(CHROMIUM), headless=True, args=["--no-sandbox", "--disable-gpu"]
        )
        try:
            page = browser.new_context(viewport={**VIEWPORT, "width": 800}).new_page()
            page.goto(path.resolve().as_uri())
            cells = page.evaluate(lines)
        finally:
            browser.close()
    assert cells and all(count == 1 for _, count in cells), [c for c in cells if c[1] != 1][:5]


def test_a_single_repetition_shows_its_value_in_the_peak_tables() -> None:
    body = _body(report_inputs(n_participants=1, n_repetitions=1, drop_first=0, with_answers=False))
    assert "Peak percent error while raising" in body and "Peak percent error while lowering" in body
    ours = [cell for cell in _cells(body) if cell.endswith("(n = 1)")]
    assert len(ours) == 2 * 3 * 3 * 2  # phases × suit conditions × speeds × (peak, time)


def test_sections_without_data_are_left_out(study: Study) -> None:
    # A lab store without a bench and without questionnaires.
    body = _body(_without_bench_or_answers(study.inputs))
    assert "Transmission identification" not in body
    assert "<h2>Questionnaires</h2>" not in body and "No questionnaire answers" not in body
    assert "Muscle activity (iEMG)" in body  # sections with data stay
    with_them = study.body
    assert "<h2>Transmission identification</h2>" in with_them and "<h2>Questionnaires</h2>" in with_them


def test_the_notes_are_condensed(study: Study) -> None:
    shown = [html.unescape(p) for p in re.findall(r'<p class="note">([^<]*)</p>', study.body)]
    assert "EMG of trials #1–#204: recorded with the trial" in shown
    assert "trials #300–#302, #305 (4 trials) skipped: it holds no samples" in shown
    assert "trial 400 (participant P01, support_50, V2) set aside: the suit stalled" in shown
    assert not any("203, 204" in note for note in shown)


def test_the_participant_figure_draws_each_conditions_reference() -> None:
    figure = participant_curves(curves(["P01"]), "P01")
    rows = figure.axes[: 5 * 3]
    torque, tension = rows[3], rows[6]  # second and third row, first speed
    for ax in (torque, tension):
        dashed = {to_hex(line.get_color()) for line in ax.get_lines() if line.get_linestyle() == "--"}
        assert dashed == {to_hex(CONDITION_COLOURS[c]) for c in CONDITIONS[1:]}
        for condition in CONDITIONS[1:]:
            ours = [line for line in ax.get_lines() if line.get_linestyle() == "--"
                    and to_hex(line.get_color()) == to_hex(CONDITION_COLOURS[condition])]
            assert len(ours) == 1 and np.ptp(ours[0].get_ydata()) > 0


def test_a_p_of_zero_or_underflowing_reads_like_the_others_and_the_papers_stay_as_printed() -> None:
    import pandas as pd

    from bowden.study.report.html import HtmlDocument

    frame = pd.DataFrame({"chi2": [12.5, 0.2, 800.0, 7.0], "p": [0.0, 1.0, 1.4e-186, 0.0123],
                          "paper p": ["0.05", "< 0.001", "–", "0.012"]})
    document = HtmlDocument("t")
    document.table(frame, "caption", "{:.3g}")
    assert _cells(document.parts[-1]) == [
        "12.5", "< 0.001", "0.05", "0.2", "1.000", "< 0.001", "800", "< 0.001", "–", "7", "0.012", "0.012",
    ]
