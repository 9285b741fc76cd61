import math

import numpy as np
import pytest

from bowden.errors import ParameterError
from bowden.protocol import MinimumJerkCycle
from bowden.web.reference import TrialReference

CYCLE = MinimumJerkCycle(low_rad=math.radians(20.0), high_rad=math.radians(100.0),
                         peak_speed_rad_s=math.radians(120.0))
REFERENCE = TrialReference(cycle=CYCLE, start_s=1.5, repetitions=3)
T = CYCLE.movement_duration_s  # 1.875 * 80 / 120 = 1.25 s


def test_movement_duration_is_the_paper_formula():
    assert pytest.approx(1.25) == T
    assert REFERENCE.end_s == pytest.approx(1.5 + 3 * 2.5)


def test_hand_derived_points():
    deg = lambda t: math.degrees(REFERENCE.elevation_rad(t))  # noqa: E731
    assert deg(0.0) == pytest.approx(20.0)
    assert deg(1.5) == pytest.approx(20.0)
    assert deg(1.5 + T / 2) == pytest.approx(60.0)  # s(1/2) = 1/2
    assert deg(1.5 + T) == pytest.approx(100.0)
    assert deg(1.5 + 1.5 * T) == pytest.approx(60.0)
    # s(1/4) = 10/64 - 15/256 + 6/1024 = 0.103515625
    assert deg(1.5 + T / 4) == pytest.approx(20.0 + 80.0 * 0.103515625)
    assert deg(REFERENCE.end_s + 0.1) == pytest.approx(20.0)


def test_agrees_with_the_protocol_cycle_during_the_repetitions():
    times = np.linspace(REFERENCE.start_s, REFERENCE.end_s - 1e-9, 2001)
    ours = np.array([REFERENCE.elevation_rad(float(t)) for t in times])
    theirs = CYCLE.elevation_rad(times - REFERENCE.start_s)
    np.testing.assert_allclose(ours, theirs, atol=1e-12)


def test_repetition_in_progress():
    assert REFERENCE.repetition(0.0) == 0
    assert REFERENCE.repetition(1.5) == 1
    assert REFERENCE.repetition(1.5 + 2.49) == 1
    assert REFERENCE.repetition(1.5 + 2.51) == 2
    assert REFERENCE.repetition(1.5 + 7.49) == 3
    assert REFERENCE.repetition(100.0) == 3


def test_display_numbers_are_in_degrees():
    assert REFERENCE.to_json() == {"low_deg": pytest.approx(20.0), "high_deg": pytest.approx(100.0),
                                   "movement_s": pytest.approx(1.25), "start_s": 1.5, "repetitions": 3}


@pytest.mark.parametrize(("field", "value"), [("start_s", -1.0), ("start_s", math.nan), ("repetitions", 0),
                                              ("repetitions", True), ("repetitions", 2.0)])
def test_parameters_are_validated(field, value):
    with pytest.raises(ParameterError, match=field):
        TrialReference(cycle=CYCLE, **{field: value})
