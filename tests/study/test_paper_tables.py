"""The paper's tables in the report's shapes, set beside the study's, and the paper's marks on box plots."""

from __future__ import annotations

import re

import pandas as pd

from bowden.analysis.outcomes import IEMG_PREFIX, SPARC
from bowden.study.report.figures import condition_boxplots
from bowden.study.report.paper_tables import (
    paper_effects_table,
    paper_means,
    paper_pairwise_table,
    paper_significance_html,
)
from bowden.study.report.study_tables import beside


def test_the_papers_tables_in_the_reports_shapes() -> None:
    s4 = paper_effects_table(None)
    assert s4.loc[("RMSE (deg)", "V1"), "no"] == "4.755 (0.299)"
    assert s4.loc[("SPARC (-)", "V3"), "p (V)"] == "< 0.001"
    s9 = paper_effects_table("lowering")
    assert s9.loc[("Post. delt.", "V3"), "p (C)"] == "< 0.001"
    s12 = paper_pairwise_table("condition", "lowering")
    assert s12.loc["Post. delt.", ("50%-no", "percent")] == "31.7"
    s5 = paper_pairwise_table("condition", None)
    assert list(s5.index) == ["SPARC (-)"] and s5.loc["SPARC (-)", ("50%-no", "p")] == "0.04"
    assert paper_means(SPARC)[("support_50", "V1")] == 2.832
    assert paper_means(IEMG_PREFIX + "anterior_deltoid")[("no_suit", "V2")] == 0.459


def test_the_paper_stands_under_the_study_outcome_by_outcome() -> None:
    ours = paper_effects_table("raising").iloc[:6]  # two muscles, as a study would give them
    both = beside(ours, paper_effects_table("raising"), "simulated")
    first = [tuple(i) for i in both.index[:12]]
    assert [i[:2] for i in first[::3]] == [("Ant. delt.", "simulated"), ("Ant. delt.", "paper"),
                                           ("Med. delt.", "simulated"), ("Med. delt.", "paper")]
    assert len(both) == 6 + 24


def test_box_plots_mark_the_papers_means() -> None:
    rows = [{"participant": p, "condition": c, "speed": s, "value": 1.0}
            for p in ("P01", "P02") for c in ("no_suit", "support_50") for s in ("V1", "V2", "V3")]
    figure = condition_boxplots(pd.DataFrame(rows), "v", "t", paper_means=paper_means(SPARC))
    marks = [c for ax in figure.axes for c in ax.collections if c.get_label() == "paper mean"]
    assert len(marks) == 3 and [tuple(o) for o in marks[0].get_offsets()] == [(1.38, 2.76), (2.38, 2.832)]


def test_the_papers_colour_table_has_its_colours_codes_and_changes() -> None:
    fragment = paper_significance_html("lowering", "caption")
    # Table 3: the posterior deltoid at 50 % against no suit, +31.7 % (Table S12), red with **.
    cell = re.search(r"Post\. delt\.</th>(.*?)</tr>", fragment, re.S)
    assert cell is not None
    td = r'<td style="background:(rgb\([^)]*\));[^"]*" title="([^"]*)">([^<]*)</td>'
    cells = re.findall(td, cell.group(1))
    headers = re.findall(r'<th style="padding:2px 8px">([^<]*)</th>', fragment)
    colour, title, code = cells[headers.index("50%-no")]
    red, green, blue = (int(v) for v in re.findall(r"\d+", colour))
    assert red == 255 and green == blue < 255  # an increase: red
    assert code == "**" and title.startswith("+31.7 %")
    assert len(headers) == 6 and len(re.findall(r'<tr><th style="text-align:left">', fragment)) == 8
