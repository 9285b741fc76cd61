import math

import pytest

from bowden.errors import RequestError
from bowden.web.validation import choice, integer_in, no_unknown_fields, number_in, participant_id


@pytest.mark.parametrize("value", ["P01", "P1", "S007", "ABCD1234"])
def test_pseudonymous_ids_are_accepted(value):
    assert participant_id(value) == value.strip()


@pytest.mark.parametrize(
    "value",
    ["Anna", "anna", "Anna Smith", "p01", "P", "01", "P01x", "P 01", "PARTI01", "P12345", "", "P01;DROP",
     " P03 ", "P01\n", 1,
     None],
)
def test_names_and_other_ids_are_refused(value):
    with pytest.raises(RequestError, match="participant"):
        participant_id(value)


def test_choice_names_the_field_and_the_options():
    assert choice("V2", ("V1", "V2"), "speed") == "V2"
    with pytest.raises(RequestError, match=r"speed: 'V9' is not one of V1, V2"):
        choice("V9", ("V1", "V2"), "speed")


def test_integers_from_json_and_forms():
    assert integer_in(7, 1, 7, "x") == 7
    assert integer_in("3", 1, 7, "x") == 3
    assert integer_in(6.0, 6, 20, "x") == 6
    for bad in (0, 8, 3.5, "3.5", "three", True, None, [3]):
        with pytest.raises(RequestError, match="x: expected an integer from 1 to 7"):
            integer_in(bad, 1, 7, "x")


def test_numbers_must_be_finite_and_in_range():
    assert number_in("1.75", 1.0, 2.3, "height_m") == 1.75
    assert number_in(2, 1.0, 2.3, "height_m") == 2.0
    for bad in (math.nan, math.inf, 175, "175", "1e999", False):
        with pytest.raises(RequestError, match="height_m"):
            number_in(bad, 1.0, 2.3, "height_m")
    with pytest.raises(RequestError, match="height_m: 'tall' is not a number"):
        number_in("tall", 1.0, 2.3, "height_m")


def test_unknown_fields_are_named():
    no_unknown_fields({"a": 1}, ("a", "b"), "trial")
    with pytest.raises(RequestError, match=r"trial: unknown field.*'partcipant'"):
        no_unknown_fields({"partcipant": "P01"}, ("participant",), "trial")
