"""The questionnaires filled in between conditions, and the validation of a submitted form.

The paper (supplement, section "Questionnaires") used, after each condition:

* a 16-site **modified Nordic questionnaire** of discomfort (Kuorinka et al. 1987, Appl Ergon
  18:233), each site on a 7-point Likert scale from "No discomfort" (1) to "Extreme discomfort" (7);
* the **Borg rating of perceived exertion** (Borg 1982, Med Sci Sports Exerc 14:377), 6–20, 6 "No
  exertion at all" to 20 "Maximal exertion";
* **perceived muscular fatigue** on a 6-site diagram (pectoralis major, deltoids, trapezius, biceps,
  triceps, latissimus dorsi), 7-point Likert from "No fatigue" (1) to "Extreme fatigue" (7).

Item names are those of the simulated cohort (:mod:`bowden.sim.questionnaires`), so answers from
the browser and from virtual participants land in the same long table
``(participant, condition, questionnaire, item, score)`` and are analysed alike.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final

from bowden.contracts import (
    BORG_HIGH,
    BORG_LOW,
    BORG_RPE_ITEM,
    FATIGUE_SITES,
    LIKERT_HIGH,
    LIKERT_LOW,
    NORDIC_SITES,
    PROTOCOL_NAME_RULE,
    QUESTIONNAIRE_BORG_RPE,
    QUESTIONNAIRE_FATIGUE,
    QUESTIONNAIRE_NORDIC,
    QUESTIONNAIRES,
    is_protocol_name,
)
from bowden.errors import RequestError
from bowden.protocol.catalogue import PAPER, Catalogue
from bowden.web.labels import condition_label
from bowden.web.validation import choice, no_unknown_fields, participant_id, whole_number_in

NORDIC: Final = QUESTIONNAIRE_NORDIC
BORG_RPE: Final = QUESTIONNAIRE_BORG_RPE
FATIGUE: Final = QUESTIONNAIRE_FATIGUE
BORG_ITEM: Final = BORG_RPE_ITEM


NORDIC_SITE_LABELS: Final = {
    "upper_neck": "Upper neck",
    "lower_neck": "Lower neck",
    "right_shoulder": "Right shoulder",
    "left_shoulder": "Left shoulder",
    "upper_back": "Upper back",
    "right_upper_arm": "Right upper arm",
    "left_upper_arm": "Left upper arm",
    "right_elbow": "Right elbow",
    "left_elbow": "Left elbow",
    "right_forearm": "Right forearm",
    "left_forearm": "Left forearm",
    "right_wrist_hand": "Right wrist and hand",
    "left_wrist_hand": "Left wrist and hand",
    "middle_back": "Middle back",
    "lower_back": "Lower back",
    "hips": "Hips and thighs",
}
FATIGUE_SITE_LABELS: Final = {
    "pectoralis_major": "Pectoralis major (chest)",
    "deltoids": "Deltoids (shoulder)",
    "trapezius": "Trapezius (neck and upper back)",
    "biceps": "Biceps (front of upper arm)",
    "triceps": "Triceps (back of upper arm)",
    "latissimus_dorsi": "Latissimus dorsi (side of the back)",
}
# Verbal anchors of the Borg 6–20 scale (Borg 1982); the even steps in between carry no words.
BORG_ANCHORS: Final = {
    6: "No exertion at all",
    7: "Extremely light",
    9: "Very light",
    11: "Light",
    13: "Somewhat hard",
    15: "Hard (heavy)",
    17: "Very hard",
    19: "Extremely hard",
    20: "Maximal exertion",
}
NORDIC_ANCHORS: Final = {1: "No discomfort", 7: "Extreme discomfort"}
FATIGUE_ANCHORS: Final = {1: "No fatigue", 7: "Extreme fatigue"}

_FORM_FIELDS: Final = ("participant", "condition", "replace", "token")
# The operator's reason for questionnaires after a condition the participant did not run.
EXCEPTION_FIELD: Final = "exception"


@dataclass(frozen=True, kw_only=True)
class QuestionnaireResponse:
    """One participant's answers after one condition (all three questionnaires, every item).

    Parameters
    ----------
    participant
        Pseudonymous id (``P01``).
    condition
        One of ``bowden.contracts.CONDITIONS`` or a lab's own (``contracts.is_protocol_name``; which
        ones a server accepts is its protocol's catalogue, :func:`parse_response`).
    nordic
        Discomfort 1–7 per site of :data:`NORDIC_SITES`, in that order.
    borg_rpe
        Rating of perceived exertion, 6–20.
    fatigue
        Fatigue 1–7 per site of :data:`FATIGUE_SITES`, in that order.
    """

    participant: str
    condition: str
    nordic: tuple[int, ...]
    borg_rpe: int
    fatigue: tuple[int, ...]

    def __post_init__(self) -> None:
        participant_id(self.participant)
        if not is_protocol_name(self.condition):
            raise RequestError(f"condition: must be {PROTOCOL_NAME_RULE}")
        if len(self.nordic) != len(NORDIC_SITES):
            raise RequestError(f"nordic: expected {len(NORDIC_SITES)} scores, got {len(self.nordic)}")
        if len(self.fatigue) != len(FATIGUE_SITES):
            raise RequestError(f"fatigue: expected {len(FATIGUE_SITES)} scores, got {len(self.fatigue)}")
        for site, score in zip(NORDIC_SITES, self.nordic, strict=True):
            whole_number_in(score, LIKERT_LOW, LIKERT_HIGH, f"nordic.{site}")
        whole_number_in(self.borg_rpe, BORG_LOW, BORG_HIGH, BORG_RPE)
        for site, score in zip(FATIGUE_SITES, self.fatigue, strict=True):
            whole_number_in(score, LIKERT_LOW, LIKERT_HIGH, f"fatigue.{site}")

    def items(self) -> list[tuple[str, str, int]]:
        """``(questionnaire, item, score)`` rows in a fixed order (the store's long format)."""
        rows = [(NORDIC, site, score) for site, score in zip(NORDIC_SITES, self.nordic, strict=True)]
        rows.append((BORG_RPE, BORG_ITEM, self.borg_rpe))
        rows.extend((FATIGUE, site, score) for site, score in zip(FATIGUE_SITES, self.fatigue, strict=True))
        return rows


def _scores(section: object, sites: tuple[str, ...], name: str) -> tuple[int, ...]:
    if not isinstance(section, Mapping):
        raise RequestError(f"{name}: expected an object with one score per site")
    no_unknown_fields(dict(section), sites, name)
    missing = [site for site in sites if site not in section]
    if missing:
        raise RequestError(f"{name}: no answer for {', '.join(missing)}")
    return tuple(whole_number_in(section[site], LIKERT_LOW, LIKERT_HIGH, f"{name}.{site}") for site in sites)


def form_scores(payload: Mapping[str, object]) -> dict[str, object]:
    """An HTML form's fields with the scores as numbers (a form can only send text).

    Only the score fields (``nordic.*``, ``fatigue.*``, ``borg_rpe``) are converted, and only whole
    digit strings; anything else is left for :func:`parse_response` to refuse. JSON requests are not
    converted: a score sent as the string "3" is refused there, as the study store refuses it.
    """
    converted: dict[str, object] = {}
    for key, value in payload.items():
        score = key == BORG_RPE or key.partition(".")[0] in (NORDIC, FATIGUE)
        if score and isinstance(value, str) and value.isascii() and value.isdigit() and len(value) <= 3:
            converted[key] = int(value)
        else:
            converted[key] = value
    return converted


def _nest_form_fields(payload: Mapping[str, object]) -> dict[str, object]:
    """Flat HTML-form fields (``nordic.upper_neck=3``) to the JSON shape (``{"nordic": {...}}``)."""
    nested: dict[str, Any] = {}
    for key, value in payload.items():
        section, dot, item = key.partition(".")
        if dot and section in (NORDIC, FATIGUE):
            nested.setdefault(section, {})[item] = value
        else:
            nested[key] = value
    return nested


def parse_response(
    payload: Mapping[str, object], catalogue: Catalogue = PAPER
) -> tuple[QuestionnaireResponse, bool]:
    """Validate a submitted questionnaire; return it and whether it may replace a stored one.

    The condition is one of ``catalogue``'s (the paper's and the protocol's own).

    Accepts the JSON shape ``{"participant", "condition", "nordic": {site: score}, "borg_rpe",
    "fatigue": {site: score}, "replace": bool}`` or the same as flat form fields
    (``nordic.upper_neck``...). Every item is required.

    Raises
    ------
    RequestError
        Naming the first field that is missing, unknown or out of range.
    """
    data = _nest_form_fields(payload)
    no_unknown_fields(data, (*_FORM_FIELDS, *QUESTIONNAIRES), "questionnaire")
    for required in ("participant", "condition", *QUESTIONNAIRES):
        if required not in data:
            raise RequestError(f"questionnaire: the field {required!r} is missing")
    replace = data.get("replace", False)
    if replace in ("1", "true", "on"):
        replace = True
    elif replace in ("0", "false", "", None):
        replace = False
    if not isinstance(replace, bool):
        raise RequestError("replace: expected true or false")
    response = QuestionnaireResponse(
        participant=participant_id(data["participant"]),
        condition=choice(data["condition"], catalogue.condition_names, "condition"),
        nordic=_scores(data[NORDIC], NORDIC_SITES, NORDIC),
        borg_rpe=whole_number_in(data[BORG_RPE], BORG_LOW, BORG_HIGH, BORG_RPE),
        fatigue=_scores(data[FATIGUE], FATIGUE_SITES, FATIGUE),
    )
    return response, replace


def questionnaire_schema(catalogue: Catalogue = PAPER) -> dict[str, object]:
    """What the browser form shows: conditions, sites with labels, scales with their verbal anchors."""
    return {
        "conditions": [{"id": c, "label": condition_label(c)} for c in catalogue.condition_names],
        NORDIC: {
            "title": "Discomfort (modified Nordic questionnaire)",
            "low": LIKERT_LOW,
            "high": LIKERT_HIGH,
            "anchors": NORDIC_ANCHORS,
            "items": [{"id": s, "label": NORDIC_SITE_LABELS[s]} for s in NORDIC_SITES],
        },
        BORG_RPE: {
            "title": "Perceived exertion (Borg RPE)",
            "low": BORG_LOW,
            "high": BORG_HIGH,
            "anchors": BORG_ANCHORS,
        },
        FATIGUE: {
            "title": "Perceived muscular fatigue",
            "low": LIKERT_LOW,
            "high": LIKERT_HIGH,
            "anchors": FATIGUE_ANCHORS,
            "items": [{"id": s, "label": FATIGUE_SITE_LABELS[s]} for s in FATIGUE_SITES],
        },
    }
