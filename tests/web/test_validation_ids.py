"""The web's participant-id check is the shared rule (contracts.is_participant_id), with its own message."""

from __future__ import annotations

import random

import pytest

from bowden.contracts import is_participant_id
from bowden.errors import RequestError
from bowden.web.validation import participant_id


def test_the_web_accepts_exactly_what_the_shared_rule_accepts() -> None:
    rng = random.Random(7)
    alphabet = "PSZ09ap \t\n-É٣"
    texts = ["".join(rng.choice(alphabet) for _ in range(rng.randint(0, 9))) for _ in range(3000)]
    for text in texts:
        try:
            accepted = participant_id(text) == text
        except RequestError:
            accepted = False
        assert accepted == is_participant_id(text), repr(text)


@pytest.mark.parametrize("text", ["PPPPP1", "P0P1", "P٣", "p7", "Anna Smith"])
def test_near_ids_are_refused_with_the_form_message(text: str) -> None:
    with pytest.raises(RequestError, match=r"^participant: .* is not a pseudonymous id; use 1–4 capital"):
        participant_id(text)
