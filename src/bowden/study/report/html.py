"""A self-contained HTML document: headings, paragraphs, tables and figures embedded as PNG data.

The report of a study is one file a researcher can mail or archive: no external assets, no scripts.
"""

from __future__ import annotations

import base64
import html
import io
import re
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pandas as pd

from bowden._atomic_file import existing_head, write_text_atomically
from bowden.errors import OutputFileError
from bowden.study.report.pvalues import format_p_columns

_STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 1100px;
       margin: 2em auto; padding: 0 1em; color: #1b1b1b; line-height: 1.45; }
h1 { border-bottom: 2px solid #444; padding-bottom: .2em; }
h2 { margin-top: 2em; border-bottom: 1px solid #bbb; }
table { border-collapse: collapse; margin: 1em 0; font-size: 0.88em; }
th, td { border: 1px solid #ccc; padding: 3px 7px; text-align: right; }
th { background: #f2f2f2; }
caption { caption-side: top; text-align: left; font-weight: 600; padding: 4px 0; }
figure { margin: 1.2em 0; }
figcaption { font-size: 0.9em; color: #444; }
img { max-width: 100%; }
pre { white-space: pre-wrap; font-size: 0.85em; }
.banner { background: #fff4d6; border: 1px solid #e0b84a; padding: .6em 1em; margin: 1em 0; }
.note { color: #555; font-size: 0.92em; }
.side-by-side { display: flex; gap: 2em; flex-wrap: wrap; align-items: flex-start; }
.table-scroll { overflow-x: auto; max-width: 100%; }
/* A number, "< 0.001" or "0.412 (0.031)" is never broken over lines: a wide table scrolls in its box
   instead; only cells of running text wrap. */
td { white-space: nowrap; }
td.text { white-space: normal; min-width: 18em; }
nav.toc { background: #f7f7f7; border: 1px solid #ddd; padding: .4em 1.2em; margin: 1em 0; }
nav.toc ol { margin: .3em 0; padding-left: 1.4em; }
nav.toc ol ol { font-size: 0.92em; }
"""


@dataclass(frozen=True)
class FigureJob:
    """A figure to draw later: ``make(*args)`` returns a matplotlib figure.

    ``make`` is a module-level function and ``args`` plain data, so that a worker process can draw it.
    """

    make: Callable[..., Any]
    args: tuple[Any, ...]
    dpi: int


def figure_png(job: FigureJob) -> bytes:
    """Draw a :class:`FigureJob` and return its PNG (a task for a worker)."""
    buffer = io.BytesIO()
    job.make(*job.args).savefig(buffer, format="png", dpi=job.dpi, bbox_inches="tight")
    return buffer.getvalue()


FigureMapper = Callable[[Callable[[FigureJob], bytes], Iterable[FigureJob]], Iterator[bytes]]


class PendingFigure(Protocol):
    """What a submitted figure task gives: its PNG, once drawn."""

    def result(self) -> bytes: ...


# Starts ``function(job)`` (on a worker) and returns its pending result, e.g. an engine's ``submit``.
FigureSubmit = Callable[[Callable[[FigureJob], bytes], FigureJob], PendingFigure]


def _serial(function: Callable[[FigureJob], bytes], jobs: Iterable[FigureJob]) -> Iterator[bytes]:
    return map(function, jobs)


@dataclass
class HtmlDocument:
    """Accumulates body fragments and writes them as one HTML file.

    ``caption_label`` (e.g. ``"simulated"``) is added to every table and figure caption that does not
    already say it, so that no table of a simulated report can be quoted as if it were measured.
    """

    title: str
    parts: list[str] = field(default_factory=list)
    caption_label: str = ""
    # Given, each figure is handed to it as soon as it is added, so that workers draw while the rest
    # of the document is built; otherwise figures wait for draw_figures().
    figure_submit: FigureSubmit | None = field(default=None, repr=False)
    # Figures not drawn yet, each behind a placeholder in ``parts``: waiting, or started.
    _pending: dict[str, tuple[FigureJob, str]] = field(default_factory=dict, repr=False)
    _started: dict[str, tuple[PendingFigure, str]] = field(default_factory=dict, repr=False)

    def _caption(self, caption: str) -> str:
        label = self.caption_label
        if label and label.lower() not in caption.lower():
            return f"{caption} ({label})"
        return caption

    def heading(self, text: str, level: int = 2) -> None:
        self.parts.append(f"<h{level}>{html.escape(text)}</h{level}>")

    @contextmanager
    def section(self, text: str, level: int = 2) -> Iterator[None]:
        """A heading kept only if something is added under it (``with document.section(...):``): a
        report leaves out a section its study has nothing for, such as the identification of a lab
        store without a bench."""
        start = len(self.parts)
        self.heading(text, level)
        yield
        if len(self.parts) == start + 1:
            del self.parts[start]

    def paragraph(self, text: str, css_class: str = "") -> None:
        attr = f' class="{css_class}"' if css_class else ""
        self.parts.append(f"<p{attr}>{html.escape(text)}</p>")

    def banner(self, text: str) -> None:
        self.parts.append(f'<div class="banner">{html.escape(text)}</div>')

    def table(self, frame: pd.DataFrame, caption: str, float_format: str = "{:.3g}") -> None:
        """A DataFrame as an HTML table with a caption; floats formatted with ``float_format``."""
        if frame.index.nlevels == 1 and frame.columns.nlevels == 1 and frame.index.name is not None:
            # The index's name goes into the header's corner instead of a row of its own.
            frame = frame.rename_axis(index=None, columns=str(frame.index.name))
        elif any(name is not None for name in frame.index.names):
            # pandas would give the index names a header row of their own, empty but for them; the row
            # labels (simulated/paper, pre/25%/50%, V1-V3) say what they are.
            frame = frame.set_axis(frame.index.set_names([None] * frame.index.nlevels), axis="index")
        # Unknown values (None in object columns, e.g. a registry's optional fields) read as missing.
        objects = frame.columns[(frame.dtypes == np.dtype(object)).to_numpy()]
        if len(objects):
            frame = frame.copy()
            frame[objects] = frame[objects].where(frame[objects].notna(), float("nan"))
        # A bare 0, 1, 2… index says nothing: leave it out.
        plain_index = isinstance(frame.index, pd.RangeIndex) and frame.index.name is None
        body = format_p_columns(frame).to_html(
            float_format=lambda v: float_format.format(v), na_rep="–", border=0, escape=True,
            index=not plain_index,
        )
        body = _LONG_CELL.sub(r'<td class="text">\1</td>', body)  # running text may wrap, numbers not
        opening_end = body.index(">") + 1  # after pandas' "<table ...>"
        caption = html.escape(self._caption(caption))
        # Wide tables scroll inside their own box instead of widening the page.
        self.parts.append(
            f'<div class="table-scroll">{body[:opening_end]}<caption>{caption}</caption>'
            f"{body[opening_end:]}</div>"
        )

    def raw_table(self, table_html: str) -> None:
        """An HTML table made elsewhere (e.g. a pandas Styler), inserted as is (in a scrolling box)."""
        self.parts.append(f'<div class="table-scroll">{table_html}</div>')

    def figure(self, fig: Any, caption: str, dpi: int = 110) -> None:
        """Embed a matplotlib figure (with a canvas attached) as a PNG data URI."""
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=dpi, bbox_inches="tight")
        self.parts.append(self._figure_html(buffer.getvalue(), caption))

    def figure_later(self, make: Callable[..., Any], *args: Any, caption: str, dpi: int = 110) -> None:
        """A figure ``make(*args)`` in this place of the document: started at once with
        :attr:`figure_submit` if given, else drawn by :meth:`draw_figures` (in worker processes, if it
        is given a parallel map)."""
        placeholder = f"<!--figure {len(self._pending) + len(self._started)} of {id(self)}-->"
        job = FigureJob(make=make, args=args, dpi=dpi)
        if self.figure_submit is not None:
            self._started[placeholder] = (self.figure_submit(figure_png, job), caption)
        else:
            self._pending[placeholder] = (job, caption)
        self.parts.append(placeholder)

    def draw_figures(self, mapper: FigureMapper = _serial) -> None:
        """Draw every figure added by :meth:`figure_later` that was not started, ``mapper(function,
        jobs)`` returning the results in the jobs' order (``map``, or a process pool's), and take those
        that were."""
        pending = list(self._pending.items())
        started = list(self._started.items())
        self._pending.clear()
        self._started.clear()
        drawn = dict(zip((placeholder for placeholder, _ in pending),
                         mapper(figure_png, [job for _, (job, _) in pending]), strict=True))
        drawn.update((placeholder, figure.result()) for placeholder, (figure, _) in started)
        captions = {placeholder: caption for placeholder, (_, caption) in pending + started}
        self.parts = [
            self._figure_html(drawn[part], captions[part]) if part in drawn else part for part in self.parts
        ]

    def _figure_html(self, png: bytes, caption: str) -> str:
        data = base64.b64encode(png).decode("ascii")
        caption = self._caption(caption)
        return (
            f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        )

    def render(self) -> str:
        if self._pending or self._started:
            self.draw_figures()
        body = "\n".join(with_contents(self.parts))
        return (
            '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            f"<title>{html.escape(self.title)}</title><style>{_STYLE}</style></head>\n"
            f"<body>\n<h1>{html.escape(self.title)}</h1>\n{body}\n</body></html>\n"
        )

    def write(self, path: str | Path) -> Path:
        """Write the document to ``path`` atomically: a crash never leaves a half-written report.

        The file gets the usual permissions (``0o666`` less the umask). An existing file is replaced
        only if it is an HTML document itself (an older report), so a wrong path cannot destroy a
        study store or a recording.

        Raises
        ------
        OutputFileError
            ``path`` is a directory, holds something other than HTML, or cannot be written (names the
            path and the reason).
        """
        path = Path(path)
        check_report_path(path)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            return write_text_atomically(path, self.render())
        except OSError as error:
            raise OutputFileError(f"cannot write the report to {path}: {error.strerror or error}") from None


# A cell of running text (a reason, a reference): longer than any number the report prints.
_LONG_CELL = re.compile(r"<td>([^<]{40,})</td>")
_HEADING = re.compile(r"^<h([23])>(.*)</h\1>$", re.S)


def _anchor(text: str, taken: set[str]) -> str:
    """A unique id for a heading: its words in lower case joined by hyphens (``-2``… if repeated)."""
    slug = re.sub(r"[^a-z0-9]+", "-", html.unescape(text).lower()).strip("-") or "section"
    anchor, n = slug, 1
    while anchor in taken:
        n += 1
        anchor = f"{slug}-{n}"
    taken.add(anchor)
    return anchor


def with_contents(parts: list[str]) -> list[str]:
    """``parts`` with an id on every section heading (h2, h3) and a table of contents linking to them,
    placed before the first section; unchanged when there is no section heading.

    Anchors are made here, when the document is complete, so that sections added by any caller (an
    appendix, a banner put in front) are listed and no two ids clash.
    """
    taken: set[str] = set()
    out: list[str] = []
    first = 0
    entries: list[tuple[int, str, str]] = []  # level, anchor, escaped text
    for part in parts:
        match = _HEADING.match(part)
        if match is None:
            out.append(part)
            continue
        level, text = int(match.group(1)), match.group(2)
        anchor = _anchor(text, taken)
        if not entries:
            first = len(out)
        entries.append((level, anchor, text))
        out.append(f'<h{level} id="{anchor}">{text}</h{level}>')
    if not entries:
        return out
    return [*out[:first], _contents(entries), *out[first:]]


def _contents(entries: list[tuple[int, str, str]]) -> str:
    """The nested list of links: each h3 under the h2 before it."""
    items: list[str] = []
    open_sublist = False
    for level, anchor, text in entries:
        link = f'<a href="#{anchor}">{text}</a>'
        if level == 3 and items:
            items.append(("" if open_sublist else "<ol>") + f"<li>{link}</li>")
            open_sublist = True
            continue
        if open_sublist:
            items.append("</ol>")
            open_sublist = False
        items.append(("</li>" if items else "") + f"<li>{link}")
    items.append(("</ol>" if open_sublist else "") + "</li>")
    return f'<nav class="toc"><strong>Contents</strong><ol>{"".join(items)}</ol></nav>'


def check_report_path(path: Path) -> None:
    """Raise ``OutputFileError`` if ``path`` is a directory or a file other than an HTML document.

    :meth:`HtmlDocument.write` checks this itself; callers about to spend minutes on a report check
    it first.
    """
    head = existing_head(path, 64, "the report")
    if head is None:
        return
    text = head.removeprefix(b"\xef\xbb\xbf").lstrip().lower()
    if text and not text.startswith((b"<!doctype html", b"<html")):
        raise OutputFileError(
            f"refusing to replace {path} by the report: it is not an HTML file (it begins {head[:16]!r}); "
            "choose another report path"
        )
