import sqlite3

import pytest

from bowden.contracts import FATIGUE_SITES, NORDIC_SITES
from bowden.errors import ConflictError
from bowden.runtime import Recorder, TrialInfo
from bowden.store.sample_chunks import sample_count
from bowden.web.questionnaire_store import QuestionnaireStore
from bowden.web.questionnaires import QuestionnaireResponse

from .conftest import store_snapshot


def response(participant="P01", condition="support_25", base=2):
    return QuestionnaireResponse(
        participant=participant,
        condition=condition,
        nordic=tuple(1 + (base + i) % 7 for i in range(len(NORDIC_SITES))),
        borg_rpe=9 + base,
        fatigue=tuple(1 + (base * i) % 7 for i in range(len(FATIGUE_SITES))),
    )


def test_a_submission_is_stored_item_by_item(tmp_path):
    store = QuestionnaireStore(tmp_path / "study.sqlite")
    assert store.save(response()) == 23
    rows = store.rows("P01", "support_25")
    assert len(rows) == 23
    by_item = {(q, item): score for _, _, q, item, score, _ in rows}
    assert by_item[("borg_rpe", "rpe")] == 11
    assert by_item[("nordic", NORDIC_SITES[0])] == 1 + 2 % 7
    assert store.submissions()[0][:2] == ("P01", "support_25")


def test_a_second_submission_is_refused_unless_it_replaces(tmp_path):
    path = tmp_path / "study.sqlite"
    store = QuestionnaireStore(path)
    store.save(response(base=2))
    before = store_snapshot(path)
    with pytest.raises(ConflictError, match="already stored"):
        store.save(response(base=5))
    assert store_snapshot(path) == before
    store.save(response(base=5), replace=True)
    assert {r[4] for r in store.rows(condition="support_25") if r[2] == "borg_rpe"} == {14}
    assert len(store.rows()) == 23


def test_participants_and_conditions_are_kept_apart(tmp_path):
    store = QuestionnaireStore(tmp_path / "study.sqlite")
    store.save(response("P01", "no_suit"))
    store.save(response("P01", "support_50"))
    store.save(response("P02", "no_suit"))
    assert len(store.rows()) == 3 * 23
    assert len(store.rows("P01")) == 2 * 23
    assert len(store.rows(condition="no_suit")) == 2 * 23


def test_the_database_itself_refuses_names_and_out_of_range_scores(tmp_path):
    path = tmp_path / "study.sqlite"
    QuestionnaireStore(path)
    insert = "INSERT INTO questionnaires VALUES (?, ?, ?, ?, ?, '2024-01-01T00:00:00')"
    bad_rows = [
        ("Anna", "no_suit", "nordic", "hips", 1),
        ("P01 Anna", "no_suit", "nordic", "hips", 1),
        ("P01", "support 75", "nordic", "hips", 1),  # not a condition name: a space
        ("P01", "75_support", "nordic", "hips", 1),  # names start with a letter
        ("P01", "no_suit", "nordic", "hips", 8),
        ("P01", "no_suit", "borg_rpe", "rpe", 21),
        ("P01", "no_suit", "sus", "q1", 3),
    ]
    with sqlite3.connect(path) as connection:
        connection.execute(insert, ("P01", "no_suit", "borg_rpe", "rpe", 20))
        for row in bad_rows:
            with pytest.raises(sqlite3.IntegrityError):
                connection.execute(insert, row)


def test_questionnaires_share_the_file_with_recorded_trials(tmp_path):
    path = tmp_path / "study.sqlite"
    with Recorder(path, TrialInfo(participant="P01", condition="no_suit", speed="V1")) as recorder:
        recorder.record((0.0,) * 10 + (1, 0))
    store = QuestionnaireStore(path)
    store.save(response("P01", "no_suit"))
    with sqlite3.connect(path) as connection:
        assert sample_count(connection) == 1
        assert connection.execute("SELECT count(*) FROM questionnaires").fetchone()[0] == 23
        assert connection.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
