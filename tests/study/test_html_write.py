"""Writing the report file: usual permissions, never over a study store, clear errors."""

from __future__ import annotations

import os
import sqlite3
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest

from bowden.errors import OutputFileError
from bowden.study.report.html import HtmlDocument


@pytest.fixture
def umask_022() -> Iterator[None]:
    previous = os.umask(0o022)
    try:
        yield
    finally:
        os.umask(previous)


def document() -> HtmlDocument:
    doc = HtmlDocument(title="Report")
    doc.paragraph("body")
    return doc


def test_report_gets_the_usual_permissions_and_replaces_an_older_report(
    tmp_path: Path, umask_022: None
) -> None:
    path = tmp_path / "report.html"
    document().write(path)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644  # 0o666 less the umask, not mkstemp's 0o600
    newer = HtmlDocument(title="Newer")
    newer.write(path)
    assert "<title>Newer</title>" in path.read_text(encoding="utf-8")
    assert [p.name for p in tmp_path.iterdir()] == ["report.html"]  # no temporary file left


def test_a_study_store_is_never_replaced_by_the_report(tmp_path: Path) -> None:
    store = tmp_path / "study.db"
    with sqlite3.connect(store) as db:
        db.execute("CREATE TABLE trials (id INTEGER)")
    before = store.read_bytes()
    with pytest.raises(OutputFileError, match=r"refusing to replace .*study\.db.*not an HTML file"):
        document().write(store)
    assert store.read_bytes() == before


def test_missing_folders_are_made(tmp_path: Path) -> None:
    path = document().write(tmp_path / "a" / "b" / "report.html")
    assert path.read_text(encoding="utf-8").startswith("<!DOCTYPE html>")


@pytest.mark.parametrize("where", ["directory", "under a file"])
def test_unwritable_paths_are_output_file_errors_naming_the_path(tmp_path: Path, where: str) -> None:
    (tmp_path / "a_file").write_text("x")
    target = tmp_path if where == "directory" else tmp_path / "a_file" / "report.html"
    with pytest.raises(OutputFileError, match=f"cannot write the report to {target}"):
        document().write(target)
