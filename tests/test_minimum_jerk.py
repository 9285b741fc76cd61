import math

import numpy as np
import pytest

from bowden.errors import ParameterError
from bowden.protocol import MinimumJerkCycle, minimum_jerk_position


def test_paper_cycle_duration_from_reference():
    # Flash & Hogan 1985: 80° at 60 °/s peak -> T = 1.875 * 80 / 60 = 2.5 s per movement.
    cycle = MinimumJerkCycle(peak_speed_rad_s=math.radians(60.0))
    assert cycle.movement_duration_s == pytest.approx(2.5)
    assert cycle.period_s == pytest.approx(5.0)


def test_endpoints_turning_point_and_peak_speed():
    cycle = MinimumJerkCycle(peak_speed_rad_s=math.radians(120.0))
    t_move = cycle.movement_duration_s
    assert cycle.elevation_rad(0.0) == pytest.approx(math.radians(20.0))
    assert cycle.elevation_rad(t_move) == pytest.approx(math.radians(100.0))
    assert cycle.elevation_rad(2 * t_move) == pytest.approx(math.radians(20.0))
    t = np.linspace(0.0, cycle.period_s, 20001)
    v = cycle.elevation_velocity_rad_s(t)
    assert v.max() == pytest.approx(math.radians(120.0), rel=1e-6)
    assert v.min() == pytest.approx(-math.radians(120.0), rel=1e-6)


def test_velocity_is_derivative_of_position():
    cycle = MinimumJerkCycle(peak_speed_rad_s=math.radians(180.0))
    t = np.linspace(0.0, 3 * cycle.period_s, 30001)
    numeric = np.gradient(cycle.elevation_rad(t), t)
    assert np.max(np.abs(numeric - cycle.elevation_velocity_rad_s(t))) < 1e-3


def test_normalised_position_hand_values():
    assert minimum_jerk_position([0.0, 0.5, 1.0]) == pytest.approx([0.0, 0.5, 1.0])
    assert minimum_jerk_position(0.25)[()] == pytest.approx(10 / 64 - 15 / 256 + 6 / 1024)


@pytest.mark.parametrize(
    "kwargs", [{"low_rad": 1.0, "high_rad": 0.5}, {"peak_speed_rad_s": 0.0}, {"low_rad": math.nan}]
)
def test_invalid_cycles_are_refused(kwargs):
    with pytest.raises(ParameterError):
        MinimumJerkCycle(**kwargs)
