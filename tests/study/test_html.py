"""The report's HTML tables: no header row spent on index names alone."""

from __future__ import annotations

import pandas as pd

from bowden.study.report.html import HtmlDocument


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


def _line_figure(points: int, colour: str):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(2, 1))
    FigureCanvasAgg(figure)
    figure.add_subplot().plot(range(points), color=colour)
    return figure


def test_later_figures_are_drawn_in_their_places_alike_in_a_pool_or_here() -> None:
    from concurrent.futures import ProcessPoolExecutor

    def build(submit=None) -> HtmlDocument:
        document = HtmlDocument(title="t", caption_label="simulated", figure_submit=submit)
        document.paragraph("before")
        document.figure_later(_line_figure, 3, "red", caption="three points")
        document.paragraph("between")
        document.figure_later(_line_figure, 5, "blue", caption="five points", dpi=50)
        document.figure(_line_figure(4, "green"), "drawn at once")
        return document

    serial = build()
    html_serial = serial.render()  # draws what is pending
    pooled = build()
    banner = HtmlDocument(title="")
    banner.banner("inserted in front after the figures were added")
    pooled.parts[:0] = banner.parts
    with ProcessPoolExecutor(2) as pool:
        pooled.draw_figures(pool.map)
    html_pooled = pooled.render()
    assert html_pooled.replace(banner.parts[0] + "\n", "") == html_serial
    # Started on the workers as they are added (while the rest is built), then collected.
    with ProcessPoolExecutor(2) as pool:
        started = build(pool.submit)
        assert started._started and not started._pending
        started.draw_figures()
    assert started.render() == html_serial
    body = html_serial.split("<body>")[1]
    order = [body.index(text) for text in ("before", "three points (simulated)", "between", "five points",
                                          "drawn at once")]
    assert order == sorted(order)
    assert body.count("<img") == 3 and "<!--figure" not in body
