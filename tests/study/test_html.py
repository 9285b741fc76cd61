"""The report's HTML tables: no header row spent on index names alone."""

from __future__ import annotations

import pandas as pd

from bowden.study.html import HtmlDocument


def _header_rows(document: HtmlDocument) -> list[str]:
    head = document.parts[-1].split("<thead>")[1].split("</thead>")[0]
    return head.split("<tr")[1:]


def test_single_index_name_goes_into_the_header_corner() -> None:
    document = HtmlDocument(title="t")
    frame = pd.DataFrame({"V1": [1.0, 2.0]}, index=pd.Index(["pre", "50%"], name="condition"))
    document.table(frame, "caption")
    rows = _header_rows(document)
    assert len(rows) == 1 and "condition" in rows[0]
    assert "<caption>caption</caption>" in document.parts[-1]


def test_multi_level_tables_have_one_header_row_per_column_level() -> None:
    columns = pd.MultiIndex.from_product([["V1", "V2"], ["entire", "raising"]], names=["speed", "phase"])
    index = pd.MultiIndex.from_product(
        [["simulated", "paper"], ["pre", "50%"]], names=["source", "condition"]
    )
    frame = pd.DataFrame([[1.0] * 4] * 4, index=index, columns=columns)
    document = HtmlDocument(title="t")
    document.table(frame, "caption")
    rows = _header_rows(document)
    assert len(rows) == 2  # speed, phase: no third row holding only "source" and "condition"
    body = document.parts[-1]
    assert "simulated" in body and "paper" in body and "raising" in body
    assert frame.index.names == ["source", "condition"]  # the caller's frame is left alone
