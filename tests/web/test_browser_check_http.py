"""Defects of the browser check that HTTP shows without a browser: each refused with a 4xx that names
the problem, and the store left as it was."""

from __future__ import annotations

import pytest

from bowden.contracts import FATIGUE_SITES, NORDIC_SITES

from .conftest import AUTH, store_snapshot, trial_request


def answers(**changes: object) -> dict[str, object]:
    body: dict[str, object] = {
        "participant": "P02", "condition": "support_25", "nordic": {s: 2 for s in NORDIC_SITES},
        "borg_rpe": 13, "fatigue": {s: 3 for s in FATIGUE_SITES}, "exception": "checking the API",
    }
    body.update(changes)
    return body


def test_json_nested_ten_thousand_deep_is_a_400_not_a_500(client, web):
    before = store_snapshot(web.config.store_path)
    deep = b'{"participant": ' + b"[" * 10_000 + b"]" * 10_000 + b"}"
    for path in ("/api/trial/start", "/api/questionnaires", "/api/participants"):
        response = client.post(path, headers={**AUTH, "Content-Type": "application/json"}, content=deep)
        assert response.status_code == 400, response.text
        assert response.json()["error"] == "the request body is not valid JSON: nested too deeply"
    assert store_snapshot(web.config.store_path) == before


def test_a_foreign_origin_is_refused_even_with_the_right_token(client, web):
    before = store_snapshot(web.config.store_path)
    foreign = {**AUTH, "Origin": "http://evil.example"}
    for path, body in (("/api/trial/start", trial_request()), ("/api/questionnaires", answers()),
                       ("/api/trial/stop", {})):
        response = client.post(path, headers=foreign, json=body)
        assert response.status_code == 403 and "another origin" in response.json()["error"], path
    assert store_snapshot(web.config.store_path) == before
    assert not web.manager.running
    # The server's own pages send their origin, and are served.
    own = client.post("/api/questionnaires", headers={**AUTH, "Origin": "http://127.0.0.1"}, json=answers())
    assert own.status_code == 201


@pytest.mark.parametrize("participant", [" P03 ", "P01\n"])
def test_ids_with_spaces_or_a_line_break_are_refused_not_trimmed(client, web, participant):
    before = store_snapshot(web.config.store_path)
    for path, body in (("/api/trial/start", trial_request(participant=participant)),
                       ("/api/questionnaires", answers(participant=participant))):
        response = client.post(path, headers=AUTH, json=body)
        assert response.status_code == 400 and "is not a pseudonymous id" in response.json()["error"]
    assert store_snapshot(web.config.store_path) == before


def test_a_score_sent_as_a_string_is_refused(client, web):
    before = store_snapshot(web.config.store_path)
    response = client.post("/api/questionnaires", headers=AUTH, json=answers(borg_rpe="13"))
    assert response.status_code == 400
    assert response.json()["error"] == "borg_rpe: expected a whole number from 6 to 20, got '13'"
    assert store_snapshot(web.config.store_path) == before
