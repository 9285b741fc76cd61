"""The one number check every parameter dataclass uses."""

import math

import pytest

from bowden.errors import ParameterError
from bowden.model.dynamic import DynamicCompensation
from bowden.model.lines import CompensationLine
from bowden.sim.parameters import MotorParameters
from bowden.validation import check_number


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, True, "1", None])
def test_non_numbers_and_non_finite_values_are_refused_by_name(value):
    with pytest.raises(ParameterError, match=r"^speed must be a finite number, got "):
        check_number(value, "speed")


def test_the_range_is_closed_unless_low_open():
    assert check_number(0, "x", 0.0, 1.0) == 0.0 and isinstance(check_number(1, "x", 0.0, 1.0), float)
    with pytest.raises(ParameterError, match=r"x = 0 is outside its valid range \(0, 1\]"):
        check_number(0, "x", 0.0, 1.0, low_open=True)
    with pytest.raises(ParameterError, match=r"x = 1.5 is outside its valid range \[0, 1\]"):
        check_number(1.5, "x", 0.0, 1.0)


def test_the_dataclasses_name_their_field():
    with pytest.raises(ParameterError, match="slope_m must be a finite number"):
        CompensationLine(intercept_nm=0.0, slope_m=math.nan)
    line = CompensationLine(intercept_nm=0.0, slope_m=0.04)
    with pytest.raises(ParameterError, match=r"DynamicCompensation.imu_latency_s = 0.5 is outside"):
        DynamicCompensation(raising=line, lowering=line, viscous_nm_s_rad=0.0, inertia_kg_m2=0.0,
                            imu_latency_s=0.5)
    with pytest.raises(ParameterError, match=r"MotorParameters.spool_radius_m = 0.0 is outside .*\(0.005"):
        MotorParameters(spool_radius_m=0.0)
