"""The departures section: the paper's own numbers agree with the paper; a flipped change is named."""

from __future__ import annotations

import pandas as pd

from bowden import contracts as c
from bowden.analysis.outcomes import IEMG_PREFIX
from bowden.study.departures import departure_summary, iemg_departures
from bowden.study.paper_values.iemg_data import IEMG, IEMG_P
from bowden.study.statistics import StudyStatistics


def outcomes_from_the_paper(flip: tuple[str, str] | None = None) -> pd.DataFrame:
    rows = []
    for (phase, muscle, speed, condition), (mean, _sd) in IEMG.items():
        value = mean
        if flip == (phase, muscle) and condition == c.CONDITION_SUPPORT_50:
            base = IEMG[(phase, muscle, speed, c.CONDITION_NO_SUIT)][0]
            value = base - (mean - base)  # the change from no suit, the other way round
        for participant in ("P01", "P02"):
            rows.append({"participant": participant, "condition": condition, "speed": speed, "phase": phase,
                         "measure": IEMG_PREFIX + muscle, "value": value})
    return pd.DataFrame(rows)


def test_the_papers_values_are_extracted_whole() -> None:
    assert len(IEMG) == 3 * 8 * 3 * 4 and len(IEMG_P) == 3 * 8
    # The abstract's findings, from the tables: posterior deltoid +32 % while lowering at 50 %.
    change = [IEMG[("lowering", "posterior_deltoid", s, "support_50")][0]
              / IEMG[("lowering", "posterior_deltoid", s, "no_suit")][0] - 1 for s in c.SPEEDS]
    assert round(100 * sum(change) / 3) == 32


def test_the_papers_own_numbers_depart_from_nothing() -> None:
    table = iemg_departures(outcomes_from_the_paper(), StudyStatistics())
    assert (table["departs in"] == "").all()
    assert departure_summary(table).startswith("72 of 72 changes")


def test_a_change_the_other_way_is_named() -> None:
    table = iemg_departures(outcomes_from_the_paper(("lowering", "posterior_deltoid")), StudyStatistics())
    flagged = table[table["departs in"].str.contains("direction")]
    assert flagged[["phase", "muscle", "condition"]].values.tolist() == [["lowering", "Post. delt.", "50%"]]
    assert "Post. delt. lowering at 50% (-32 % against +32 %)" in departure_summary(table)
