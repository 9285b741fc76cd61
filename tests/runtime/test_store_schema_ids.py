"""The recorder's TrialInfo and the questionnaire table's SQL CHECK apply the one participant-id rule."""

from __future__ import annotations

import random
import sqlite3

import pytest

from bowden.contracts import is_participant_id
from bowden.errors import ParameterError
from bowden.runtime import TrialInfo
from bowden.store.tables import QUESTIONNAIRES_DDL

IDS = ["P07", "P1", "S112", "ABCD1234"]
NOT_IDS = ["p7", "7", "P07\n", "P07 ", " P07", "Anna Smith", "Anna", "P0P1", "PPPPP1", "P12345", "", "P-01",
           "É01", "P٣"]


def _random_texts(count: int) -> list[str]:
    """Short strings over capitals, digits and a few troublemakers (seeded: the same every run)."""
    rng = random.Random(20240607)
    alphabet = "PSAZ0179pa \n-É"
    texts = ["".join(rng.choice(alphabet) for _ in range(rng.randint(0, 9))) for _ in range(count)]
    return list(dict.fromkeys(texts + IDS + NOT_IDS))  # each once: the table's key refuses repeats


@pytest.mark.parametrize("text", ["Anna Smith", "P07\n", "p7", "BENCH"])
def test_trial_info_refuses_names_and_near_ids(text: str) -> None:
    with pytest.raises(ParameterError, match=r"TrialInfo\.participant must be a pseudonymous id"):
        TrialInfo(participant=text, condition="no_suit")


def test_trial_info_accepts_ids() -> None:
    for text in IDS:
        assert TrialInfo(participant=text, condition="no_suit").participant == text


def test_the_questionnaire_table_check_is_the_same_rule() -> None:
    with sqlite3.connect(":memory:") as connection:
        connection.execute(QUESTIONNAIRES_DDL)
        for text in _random_texts(3000):
            try:
                connection.execute(
                    "INSERT INTO questionnaires VALUES (?, 'no_suit', 'borg_rpe', 'rpe', 10, 'now')", (text,)
                )
                stored = True
            except sqlite3.IntegrityError:
                stored = False
            assert stored == is_participant_id(text), text
    connection.close()
