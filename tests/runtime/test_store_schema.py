"""The store schema refuses files that are not bowden stores and leaves them byte for byte unchanged."""

from __future__ import annotations

import socket
import sqlite3
from collections.abc import Callable
from pathlib import Path

import pytest

from bowden.cli import main
from bowden.contracts import TRIAL_COLUMNS
from bowden.errors import StoreError
from bowden.runtime import Recorder, TrialInfo
from bowden.store.schema import (
    LEGACY_TABLES,
    SCHEMA_VERSION,
    STORE_TABLES,
    check_store,
    configure_connection,
    create_schema,
)
from bowden.store.study_store import StudyStore
from bowden.web.questionnaire_store import QuestionnaireStore

TRIAL = TrialInfo(participant="P01", condition="no_suit", speed="V1")


def _files(path: Path) -> dict[str, bytes]:
    """The bytes of the file and of any journal or WAL beside it."""
    return {p.name: p.read_bytes() for p in sorted(path.parent.glob(path.name + "*"))}


def _tables(path: Path) -> dict[str, tuple[str, ...]]:
    with sqlite3.connect(path) as connection:
        names = [
            r[0]
            for r in connection.execute(
                "SELECT name FROM sqlite_master WHERE type = 'table' AND name NOT LIKE 'sqlite_%'"
            )
        ]
        return {
            name: tuple(r[1] for r in connection.execute(f'PRAGMA table_info("{name}")')) for name in names
        }


def _user_version(path: Path) -> int:
    with sqlite3.connect(path) as connection:
        return int(connection.execute("PRAGMA user_version").fetchone()[0])


def _runtime_open(path: Path) -> None:
    connection = sqlite3.connect(path)
    try:
        configure_connection(connection)
        create_schema(connection)
    finally:
        connection.close()


def _study_open(path: Path) -> None:
    StudyStore(path).close()


def _recorder_open(path: Path) -> None:
    with Recorder(path, TRIAL):
        pass


def _questionnaire_open(path: Path) -> None:
    QuestionnaireStore(path)


OPENERS: dict[str, Callable[[Path], None]] = {
    "runtime": _runtime_open,
    "study": _study_open,
    "recorder": _recorder_open,
    "questionnaires": _questionnaire_open,
}


def _foreign(path: Path) -> Path:
    with sqlite3.connect(path) as connection:
        connection.execute("CREATE TABLE foo (x)")
        connection.execute("INSERT INTO foo VALUES (1)")
    connection.close()
    return path


def _old_layout(path: Path, missing: str) -> Path:
    """A version-0 store of every bowden table, with ``missing`` left out of the samples table."""
    StudyStore(path).close()
    with sqlite3.connect(path) as connection:
        columns = [c for c in STORE_TABLES["samples"] if c != missing]
        connection.execute("DROP TABLE IF EXISTS samples")
        connection.execute(f"CREATE TABLE samples ({', '.join(columns)})")
        connection.execute("PRAGMA user_version=0")
    connection.close()
    # Back to a rollback journal, as a pre-versioning file would be, with nothing left in a WAL.
    with sqlite3.connect(path) as connection:
        connection.execute("PRAGMA journal_mode=DELETE")
    connection.close()
    return path


def test_store_tables_list_every_table_bowden_creates_with_its_columns(tmp_path: Path) -> None:
    path = tmp_path / "study.db"
    StudyStore(path).close()
    with Recorder(path, TRIAL):
        pass
    QuestionnaireStore(path)
    # Old stores' row tables are read, never created.
    assert _tables(path) == {name: cols for name, cols in STORE_TABLES.items() if name not in LEGACY_TABLES}


@pytest.mark.parametrize("opener", OPENERS)
def test_a_foreign_sqlite_file_is_refused_and_left_unchanged(tmp_path: Path, opener: str) -> None:
    path = _foreign(tmp_path / "other.db")
    before = _files(path)
    with pytest.raises(StoreError, match=r"other\.db: not a bowden study store: it holds 'foo'"):
        OPENERS[opener](path)
    assert _files(path) == before


@pytest.mark.parametrize("missing", ["reference_elevation_rad", "moment_arm_m"])
@pytest.mark.parametrize("opener", OPENERS)
def test_an_old_layout_is_refused_naming_the_column_and_left_unchanged(
    tmp_path: Path, opener: str, missing: str
) -> None:
    assert missing in TRIAL_COLUMNS
    path = _old_layout(tmp_path / "old.db", missing)
    before = _files(path)
    with pytest.raises(StoreError, match=rf"old\.db: table 'samples' lacks the column\(s\) {missing}:"):
        OPENERS[opener](path)
    assert _files(path) == before
    assert _user_version(path) == 0


@pytest.mark.parametrize("opener", OPENERS)
def test_a_newer_store_is_refused_before_the_journal_is_switched(tmp_path: Path, opener: str) -> None:
    path = tmp_path / "newer.db"
    with sqlite3.connect(path) as connection:
        connection.execute("CREATE TABLE trials (id INTEGER PRIMARY KEY)")
        connection.execute(f"PRAGMA user_version={SCHEMA_VERSION + 6}")
    connection.close()
    before = _files(path)
    with pytest.raises(StoreError, match=rf"newer\.db: .*version {SCHEMA_VERSION + 6}.*upgrade bowden"):
        OPENERS[opener](path)
    assert _files(path) == before


def test_a_file_that_is_not_sqlite_is_refused_unchanged(tmp_path: Path) -> None:
    path = tmp_path / "report.html"
    path.write_text("<!DOCTYPE html>\n<html><body>a report, not a store</body></html>\n" * 20)
    before = _files(path)
    with pytest.raises(StoreError, match=r"report\.html: cannot be read as a bowden study store"):
        _study_open(path)
    assert _files(path) == before


@pytest.mark.parametrize("opener", OPENERS)
def test_an_empty_file_becomes_a_store(tmp_path: Path, opener: str) -> None:
    path = tmp_path / "new.db"
    path.touch()  # an empty file, as `touch` or a crashed create leaves it
    OPENERS[opener](path)
    assert _user_version(path) == SCHEMA_VERSION
    assert {"trials", "sample_chunks", "events"} <= set(_tables(path))


def test_an_unstamped_store_of_bowden_tables_is_adopted(tmp_path: Path) -> None:
    # A questionnaire-only file (what `bowden serve` made before it stamped versions) is bowden's.
    path = tmp_path / "forms.db"
    from bowden.store.tables import QUESTIONNAIRES_DDL

    with sqlite3.connect(path) as connection:
        connection.execute(QUESTIONNAIRES_DDL)
    connection.close()
    with Recorder(path, TRIAL):
        pass
    assert _user_version(path) == SCHEMA_VERSION
    assert {"trials", "sample_chunks", "events", "questionnaires"} == set(_tables(path))


def test_check_store_accepts_a_current_store(tmp_path: Path) -> None:
    path = tmp_path / "study.db"
    StudyStore(path).close()
    with sqlite3.connect(path) as connection:
        check_store(connection)
    connection.close()


def test_analyze_refuses_a_foreign_file_without_touching_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _foreign(tmp_path / "foreign.db")
    before = _files(path)
    assert main(["analyze", str(path)]) == 1
    assert "not a bowden study store" in capsys.readouterr().err
    assert _files(path) == before
    assert not (tmp_path / "foreign.db-wal").exists()


def test_analyze_refuses_an_old_layout_without_stamping_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _old_layout(tmp_path / "old.db", "reference_elevation_rad")
    before = _files(path)
    assert main(["analyze", str(path)]) == 1
    assert "lacks the column(s) reference_elevation_rad" in capsys.readouterr().err
    assert _files(path) == before
    assert _user_version(path) == 0


@pytest.mark.parametrize("kind", ["newer", "foreign"])
def test_serve_refuses_a_newer_or_foreign_store_at_start_up(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str
) -> None:
    path = tmp_path / "study.db"
    if kind == "newer":
        StudyStore(path).close()
        with sqlite3.connect(path) as connection:
            connection.execute(f"PRAGMA user_version={SCHEMA_VERSION + 6}")
        connection.close()
        expected = "upgrade bowden"
    else:
        _foreign(path)
        expected = "not a bowden study store"
    before = _files(path)
    # The port is taken: should the store check not refuse, serve stops at "cannot listen", not serve.
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        code = main(["serve", "--store", str(path), "--port", str(busy.getsockname()[1])])
    assert code == 1
    error = capsys.readouterr().err
    assert expected in error and "study.db" in error and "cannot listen" not in error
    assert _files(path) == before
