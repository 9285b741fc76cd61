import pytest

from bowden.contracts import CONDITIONS, FATIGUE_SITES, NORDIC_SITES
from bowden.errors import RequestError
from bowden.web.questionnaires import (
    FATIGUE_SITE_LABELS,
    NORDIC_SITE_LABELS,
    QuestionnaireResponse,
    form_scores,
    parse_response,
    questionnaire_schema,
)


def answers(**changes):
    body = {
        "participant": "P03",
        "condition": "pretension",
        "nordic": {site: 1 + i % 7 for i, site in enumerate(NORDIC_SITES)},
        "borg_rpe": 11,
        "fatigue": {site: 7 - i for i, site in enumerate(FATIGUE_SITES)},
    }
    body.update(changes)
    return body


def test_the_paper_instruments_have_the_published_sizes():
    # Supplement, "Questionnaires": 16 Nordic sites, 6 fatigue sites, both 7-point; Borg 6-20.
    assert len(NORDIC_SITES) == 16 and set(NORDIC_SITE_LABELS) == set(NORDIC_SITES)
    assert set(FATIGUE_SITES) == {"pectoralis_major", "deltoids", "trapezius", "biceps", "triceps",
                                  "latissimus_dorsi"}
    assert set(FATIGUE_SITE_LABELS) == set(FATIGUE_SITES)
    schema = questionnaire_schema()
    assert (schema["nordic"]["low"], schema["nordic"]["high"]) == (1, 7)
    assert (schema["borg_rpe"]["low"], schema["borg_rpe"]["high"]) == (6, 20)
    assert schema["borg_rpe"]["anchors"][6] == "No exertion at all"
    assert schema["borg_rpe"]["anchors"][20] == "Maximal exertion"
    assert [c["id"] for c in schema["conditions"]] == list(CONDITIONS)


def test_a_complete_json_submission_gives_every_item_in_order():
    response, replace = parse_response(answers())
    assert not replace
    items = response.items()
    assert len(items) == 16 + 1 + 6
    assert items[0] == ("nordic", NORDIC_SITES[0], 1)
    assert items[16] == ("borg_rpe", "rpe", 11)
    assert items[-1] == ("fatigue", FATIGUE_SITES[-1], 2)


def test_flat_form_fields_are_the_same_submission():
    body = answers()
    flat = {"participant": "P03", "condition": "pretension", "borg_rpe": "11", "replace": "on"}
    flat.update({f"nordic.{site}": str(score) for site, score in body["nordic"].items()})
    flat.update({f"fatigue.{site}": str(score) for site, score in body["fatigue"].items()})
    response, replace = parse_response(form_scores(flat))
    assert replace
    assert response == parse_response(body)[0]


def test_a_score_sent_as_text_in_json_is_refused_as_the_store_refuses_it():
    body = answers()
    body["borg_rpe"] = "13"
    with pytest.raises(RequestError, match=r"borg_rpe: expected a whole number from 6 to 20, got '13'"):
        parse_response(body)
    body = answers()
    body["nordic"]["hips"] = "3"
    with pytest.raises(RequestError, match=r"nordic\.hips: expected a whole number"):
        parse_response(body)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"borg_rpe": 21}, "borg_rpe: expected an integer from 6 to 20"),
        ({"borg_rpe": 5}, "borg_rpe: expected an integer from 6 to 20"),
        ({"condition": "support_75"}, "condition"),
        ({"participant": "Maria Rossi"}, "participant"),
        ({"extra": 1}, "unknown field"),
        ({"replace": "maybe"}, "replace"),
    ],
)
def test_invalid_answers_name_the_field(change, message):
    with pytest.raises(RequestError, match=message):
        parse_response(answers(**change))


def test_every_site_is_required_and_checked():
    body = answers()
    del body["nordic"]["hips"]
    with pytest.raises(RequestError, match="nordic: no answer for hips"):
        parse_response(body)
    body = answers()
    body["fatigue"]["biceps"] = 8
    with pytest.raises(RequestError, match=r"fatigue\.biceps: expected an integer from 1 to 7"):
        parse_response(body)
    body = answers()
    body["nordic"]["left_knee"] = 1
    with pytest.raises(RequestError, match=r"nordic: unknown field.*left_knee"):
        parse_response(body)
    body = answers()
    del body["fatigue"]
    with pytest.raises(RequestError, match="'fatigue' is missing"):
        parse_response(body)


def test_the_dataclass_validates_itself():
    with pytest.raises(RequestError, match="nordic: expected 16 scores"):
        QuestionnaireResponse(participant="P01", condition="no_suit", nordic=(1,) * 15, borg_rpe=6,
                              fatigue=(1,) * 6)
