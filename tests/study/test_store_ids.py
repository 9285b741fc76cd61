"""One participant-id rule everywhere (contracts.is_participant_id), and checked questionnaire writes."""

from __future__ import annotations

import math
import sqlite3
from pathlib import Path

import pandas as pd
import pytest

from bowden.contracts import FATIGUE_SITES, NORDIC_SITES, is_participant_id
from bowden.errors import StoreError
from bowden.model import Subject
from bowden.store.study_store import StudyStore, check_participant_id
from bowden.web.questionnaire_store import QuestionnaireStore

SUBJECT = Subject(height_m=1.70, mass_kg=63.0, sex="female")
NOT_IDS = ["p7", "7", "P07\n", "P07 ", " P07", "Anna Smith", "Anna", "P0P1", "PPPPP1", "P12345", "", "P-01",
           "É01", "P٣"]
IDS = ["P07", "P1", "S112", "ABCD1234"]


@pytest.mark.parametrize("text", NOT_IDS)
def test_the_store_refuses_what_is_not_an_id(tmp_path: Path, text: str) -> None:
    assert not is_participant_id(text)
    with StudyStore(tmp_path / "study.db") as store:
        with pytest.raises(StoreError, match="not pseudonymous"):
            store.add_participant(text, SUBJECT)
        assert store.participants().empty


@pytest.mark.parametrize("text", IDS)
def test_the_store_accepts_ids(tmp_path: Path, text: str) -> None:
    assert check_participant_id(text) == text
    with StudyStore(tmp_path / "study.db") as store:
        store.add_participant(text, SUBJECT)
        assert store.participants()["id"].tolist() == [text]


def _answers(**changes: object) -> pd.DataFrame:
    rows = [
        {"participant": "P01", "condition": "support_25", "questionnaire": "nordic", "item": NORDIC_SITES[0],
         "score": 3},
        {"participant": "P01", "condition": "support_25", "questionnaire": "borg_rpe", "item": "rpe",
         "score": 13},
        {"participant": "P01", "condition": "support_25", "questionnaire": "fatigue",
         "item": FATIGUE_SITES[3], "score": 7},
    ]
    rows[2].update(changes)
    return pd.DataFrame(rows)


def test_valid_answers_are_stored(tmp_path: Path) -> None:
    with StudyStore(tmp_path / "study.db") as store:
        store.write_questionnaires(_answers())
        stored = store.questionnaires()
    assert sorted(stored["score"].tolist()) == [3, 7, 13]
    assert set(stored["participant"]) == {"P01"}


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"participant": "p7"}, r"row 2: participant 'p7' is not a pseudonymous id"),
        ({"participant": "P07\n"}, r"row 2: participant 'P07\\n' is not a pseudonymous id"),
        ({"participant": "Anna Smith"}, r"row 2: participant 'Anna Smith'"),
        ({"condition": "fifty %"}, r"row 2: condition 'fifty %' is not a condition name"),
        ({"questionnaire": "sus"}, r"row 2: unknown questionnaire 'sus'"),
        ({"item": "knee"}, r"row 2: fatigue has no item 'knee'"),
        ({"score": 25}, r"row 2: score 25 of fatigue.biceps must be a whole number from 1 to 7"),
        ({"score": 0}, r"row 2: score 0 of fatigue.biceps must be a whole number from 1 to 7"),
        ({"score": 2.5}, r"row 2: score 2.5 of fatigue.biceps must be a whole number"),
        ({"score": math.nan}, r"row 2: score of fatigue.biceps is missing \(nan\)"),
        ({"score": "5"}, r"row 2: score '5' of fatigue.biceps is not a number"),
        ({"score": True}, r"row 2: score True of fatigue.biceps is not a number"),
        ({"questionnaire": "borg_rpe", "item": "rpe", "score": 5}, r"from 6 to 20"),
    ],
)
def test_invalid_answers_are_refused_by_row_and_nothing_is_stored(
    tmp_path: Path, changes: dict[str, object], message: str
) -> None:
    assert FATIGUE_SITES[3] == "biceps"
    with StudyStore(tmp_path / "study.db") as store:
        with pytest.raises(StoreError, match=message):
            store.write_questionnaires(_answers(**changes))
        assert store.questionnaires().empty


def test_a_database_failure_is_a_store_error(tmp_path: Path) -> None:
    path = tmp_path / "study.db"
    with StudyStore(path) as store:
        # A trigger stands in for any refusal by SQLite itself (a full disk, a lock, a constraint).
        store._db.execute(
            "CREATE TRIGGER no_answers BEFORE INSERT ON questionnaires "
            "BEGIN SELECT RAISE(ABORT, 'disk says no'); END"
        )
        with pytest.raises(StoreError, match=r"cannot write the questionnaire answers into .*disk says no"):
            store.write_questionnaires(_answers())
        store.close()
        with pytest.raises(StoreError, match="cannot write the questionnaire answers"):
            store.write_questionnaires(_answers())


def test_ids_stored_under_the_older_looser_rule_stay_readable(tmp_path: Path) -> None:
    path = tmp_path / "study.db"
    StudyStore(path).close()
    with sqlite3.connect(path) as connection:
        # What the older rules let in: a lower-case id (store), a long letter run (questionnaire CHECK).
        connection.execute(
            "INSERT INTO participants (id, sex, height_m, mass_kg) VALUES ('p7', 'male', 1.8, 80)"
        )
        connection.execute(
            "INSERT INTO trials (participant, condition, speed, started_utc, ended_utc) "
            "VALUES ('p7', 'no_suit', 'V1', 'then', 'later')"
        )
        connection.execute("DROP TABLE questionnaires")
        connection.execute(
            "CREATE TABLE questionnaires (participant TEXT NOT NULL CHECK ("
            "length(participant) BETWEEN 2 AND 8 AND participant GLOB '[A-Z]*[0-9]' "
            "AND participant NOT GLOB '*[^A-Z0-9]*'), condition TEXT NOT NULL, "
            "questionnaire TEXT NOT NULL, item TEXT NOT NULL, score INTEGER NOT NULL, "
            "submitted_utc TEXT NOT NULL, PRIMARY KEY (participant, condition, questionnaire, item)) STRICT"
        )
        connection.execute(
            "INSERT INTO questionnaires VALUES ('PPPPP1', 'no_suit', 'borg_rpe', 'rpe', 9, 'then')"
        )
    connection.close()
    with StudyStore(path) as store:
        assert store.participants()["id"].tolist() == ["p7"]
        assert store.subject("p7").mass_kg == 80.0
        assert [t.participant for t in store.completed_trials()] == ["p7"]
        assert store.questionnaires()["participant"].tolist() == ["PPPPP1"]
        store.write_questionnaires(_answers())  # new answers under the one rule still go in
        assert len(store.questionnaires()) == 4
    forms = QuestionnaireStore(path)
    assert [row[0] for row in forms.rows()] == ["P01", "P01", "P01", "PPPPP1"]
    assert forms.submissions()[-1][:2] == ("PPPPP1", "no_suit")
