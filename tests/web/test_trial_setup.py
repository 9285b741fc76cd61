import math

import pytest

from bowden.control import Controller
from bowden.errors import ParameterError, RequestError
from bowden.model import CompensationLine, CompensationModel
from bowden.web.trial_setup import NoAssistance, controller_for, parse_setup, tension_estimate_n

from .conftest import trial_request


def test_support_follows_the_condition_by_default():
    assert parse_setup(trial_request(condition="support_25")).support == 0.25
    assert parse_setup(trial_request(condition="support_50")).support == 0.5
    assert parse_setup(trial_request(condition="pretension")).support == "pretension"
    assert parse_setup(trial_request(condition="no_suit")).support is None
    assert parse_setup(trial_request(condition="support_50", support="0.5")).support == 0.5


def test_a_support_that_contradicts_the_condition_is_refused_as_bowden_run_does():
    with pytest.raises(RequestError, match=r"support: support_50 means support 0\.5"):
        parse_setup(trial_request(condition="support_50", support="0.4"))


def test_support_cannot_be_set_without_a_support_condition():
    with pytest.raises(RequestError, match="support: the no_suit condition"):
        parse_setup(trial_request(condition="no_suit", support=0.5))
    with pytest.raises(RequestError, match="support: expected a number from 0 to 1"):
        parse_setup(trial_request(support=1.5))


def test_the_trial_lasts_lead_in_plus_repetitions_plus_rest():
    setup = parse_setup(trial_request(speed="V1", repetitions=2, lead_in_s=1.0))
    movement = 1.875 * 80.0 / 60.0  # paper: 80 deg at 60 deg/s peak -> 2.5 s
    assert setup.reference.cycle.movement_duration_s == pytest.approx(movement)
    assert setup.duration_s == pytest.approx(1.0 + 2 * 2 * movement + 1.0)
    assert setup.recorded_support == 0.5


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"participant": "Jane"}, "participant"),
        ({"speed": "V4"}, "speed"),
        ({"height_m": 170}, "height_m"),
        ({"sex": "x"}, "sex"),
        ({"repetitions": 0}, "repetitions"),
        ({"colour": "red"}, "unknown field"),
    ],
)
def test_bad_requests_name_the_field(change, message):
    with pytest.raises(RequestError, match=message):
        parse_setup(trial_request(**change))


def test_missing_fields_are_named():
    body = trial_request()
    del body["mass_kg"]
    with pytest.raises(RequestError, match="'mass_kg' is missing"):
        parse_setup(body)


def test_controllers_per_condition():
    model = CompensationModel.from_friction(k=0.1)
    assert isinstance(controller_for(parse_setup(trial_request(condition="no_suit")), model), NoAssistance)
    command = NoAssistance().step(0.0, 1.0, 0.5)
    assert command.torque_nm == 0.0 and math.isnan(command.tension_n) and command.faults == 0
    pre = controller_for(parse_setup(trial_request(condition="pretension")), model)
    assert isinstance(pre, Controller)
    assert pre.step(0.0, math.radians(60.0), 0.0).tension_n == pytest.approx(10.0)


@pytest.mark.parametrize("velocity", [-3.0, -1.0, -0.2, 0.0, 0.3, 1.0, 4.0])
@pytest.mark.parametrize("tension", [0.0, 12.5, 60.0])
def test_the_tension_estimate_inverts_the_model(velocity, tension):
    model = CompensationModel(
        raising=CompensationLine(intercept_nm=0.12, slope_m=0.046),
        lowering=CompensationLine(intercept_nm=-0.05, slope_m=0.027),
    )
    torque = model.torque_nm(tension, velocity)
    assert tension_estimate_n(model, torque, velocity) == pytest.approx(tension, abs=1e-9)


def test_reference_parameters_are_validated_through_the_setup():
    with pytest.raises(RequestError, match="lead_in_s"):
        parse_setup(trial_request(lead_in_s=-1))
    with pytest.raises((RequestError, ParameterError), match="mass_kg"):
        parse_setup(trial_request(mass_kg=10))
