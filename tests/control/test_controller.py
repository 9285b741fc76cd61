import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bowden.control import Command, ControllerLimits, Fault, Limit, build_controller
from bowden.errors import ModelFileError, ParameterError
from bowden.model import (
    AssistanceParameters,
    CompensationLine,
    CompensationModel,
    CuffGeometry,
    Subject,
    arm_model,
    desired_tension_n,
)
from bowden.model.model_file import save_model

SUBJECT = Subject(height_m=1.70, mass_kg=63.0, sex="female")
MODEL = CompensationModel(
    raising=CompensationLine(intercept_nm=0.06, slope_m=0.045),
    lowering=CompensationLine(intercept_nm=-0.05, slope_m=0.026),
)
FREE = ControllerLimits(max_torque_rate_nm_s=1e9, max_torque_nm=100.0, max_tension_n=1e4)
elevations = st.floats(min_value=0.0, max_value=math.radians(140.0))
velocities = st.floats(min_value=-6.0, max_value=6.0)


def controller(support=0.5, limits=FREE, **kwargs):
    return build_controller(model=MODEL, support=support, subject=SUBJECT, limits=limits, **kwargs)


@given(elevations, velocities, st.sampled_from([0.25, 0.5, "pretension"]))
def test_step_equals_composition_of_the_model_functions(theta, velocity, support):
    ctrl = controller(support)
    cmd = ctrl.step(0.0, theta, velocity)
    assistance = AssistanceParameters(support=support)
    tension = desired_tension_n(theta, arm_model(SUBJECT, 0.5), CuffGeometry(), assistance)
    assert cmd.faults == 0
    assert cmd.tension_n == pytest.approx(tension, rel=1e-12)
    assert cmd.moment_arm_m == pytest.approx(CuffGeometry().moment_arm_m(theta), rel=1e-12)
    assert cmd.torque_nm == pytest.approx(max(0.0, MODEL.torque_nm(tension, velocity)), rel=1e-12, abs=1e-15)


def test_hand_computed_cycle():
    # 90 deg, raising fast: raising line on T = 0.5 * tau_g / r.
    ctrl = controller()
    cmd = ctrl.step(0.0, math.pi / 2, 5.0)
    tau_g = 9.80665 * arm_model(SUBJECT, 0.5).total_moment_kg_m
    a, b, psi = 0.12, 0.18, math.radians(160.0)
    alpha = psi - math.pi / 2
    r = a * b * math.sin(alpha) / math.sqrt(a * a + b * b - 2 * a * b * math.cos(alpha))
    tension = 0.5 * tau_g / r
    w = 1.0 / (1.0 + math.exp(-math.log(99) * 5.0))
    expected = (-0.05 + 0.026 * tension) + ((0.06 + 0.045 * tension) - (-0.05 + 0.026 * tension)) * w
    assert cmd == Command((pytest.approx(expected), pytest.approx(tension), pytest.approx(r), 0, 0))
    assert cmd == Command.of(torque_nm=cmd.torque_nm, tension_n=cmd.tension_n, moment_arm_m=cmd.moment_arm_m)
    assert cmd._asdict()["tension_n"] == cmd.tension_n and repr(cmd).startswith("Command(torque_nm=")


@given(elevations, velocities, st.floats(-1.0, 10.0))
def test_never_a_negative_torque_or_tension(theta, velocity, intercept):
    model = CompensationModel(
        raising=CompensationLine(intercept_nm=-intercept, slope_m=0.04),
        lowering=CompensationLine(intercept_nm=-intercept, slope_m=0.03),
    )
    ctrl = build_controller(model=model, support=0.25, subject=SUBJECT, floor_tension_n=0.0)
    cmd = ctrl.step(0.0, theta, velocity)
    assert cmd.torque_nm >= 0.0
    assert cmd.tension_n >= 0.0


def test_torque_and_tension_clamped_to_limits():
    limits = ControllerLimits(max_torque_nm=1.0, max_tension_n=30.0, max_torque_rate_nm_s=1e9)
    cmd = controller(limits=limits).step(0.0, math.pi / 2, 2.0)
    assert cmd.tension_n == 30.0
    assert cmd.torque_nm == 1.0
    assert cmd.limits == Limit.TENSION | Limit.TORQUE


def test_torque_rate_limited_and_ramps_up():
    limits = ControllerLimits(max_torque_rate_nm_s=50.0)
    ctrl = controller(limits=limits)
    first = ctrl.step(0.0, math.pi / 2, 0.0)
    assert first.torque_nm == pytest.approx(50.0 * 0.002)  # nominal period on the first cycle
    assert first.limits & Limit.TORQUE_RATE
    second = ctrl.step(0.004, math.pi / 2, 0.0)
    assert second.torque_nm - first.torque_nm == pytest.approx(50.0 * 0.004)
    target = MODEL.torque_nm(second.tension_n, 0.0)
    t, cmd = 0.004, second
    while cmd.limits & Limit.TORQUE_RATE:
        t += 0.002
        cmd = ctrl.step(t, math.pi / 2, 0.0)
    assert cmd.torque_nm == pytest.approx(target)
    # Going down is rate limited too.
    dropped = ctrl.step(t + 0.002, math.radians(25.0), 0.0)
    assert dropped.torque_nm == pytest.approx(cmd.torque_nm - 50.0 * 0.002)


@pytest.mark.parametrize(
    ("inputs", "fault"),
    [
        ((0.0, math.nan, 0.0), Fault.NONFINITE_INPUT),
        ((0.0, 1.0, math.inf), Fault.NONFINITE_INPUT),
        ((math.nan, 1.0, 0.0), Fault.NONFINITE_INPUT),
        ((0.0, 1.0, 0.0, -math.inf), Fault.NONFINITE_INPUT),
        ((0.0, 1.0, 0.0, 0.0, math.inf), Fault.NONFINITE_INPUT),
        ((0.0, math.radians(170.0), 0.0), Fault.ELEVATION_OUT_OF_RANGE),
        ((0.0, -1.0, 0.0), Fault.ELEVATION_OUT_OF_RANGE),
        ((0.0, 1.0, 50.0), Fault.ELEVATION_VELOCITY_OUT_OF_RANGE),
        ((0.0, 1.0, 0.0, 100.0), Fault.MOTOR_OVERSPEED),
    ],
)
def test_bad_inputs_give_the_safe_command_with_a_flag(inputs, fault):
    ctrl = controller()
    ctrl.step(-0.002, 1.0, 0.0)
    cmd = ctrl.step(*inputs)
    assert cmd.torque_nm == 0.0
    assert cmd.faults == fault
    assert math.isnan(cmd.tension_n)
    assert ctrl.last_torque_nm == 0.0


def test_recovery_after_a_fault_ramps_from_zero():
    ctrl = controller(limits=ControllerLimits(max_torque_rate_nm_s=10.0))
    ctrl.step(0.0, math.nan, 0.0)
    cmd = ctrl.step(0.002, math.pi / 2, 0.0)
    assert cmd.faults == 0
    assert cmd.torque_nm == pytest.approx(0.02)


def test_missing_motor_readings_are_accepted():
    cmd = controller().step(0.0, 1.0, 0.3, math.nan, math.nan)
    assert cmd.faults == 0 and cmd.torque_nm > 0.0


@given(elevations, velocities, st.floats(1e-6, 1e-3), st.floats(1e-6, 1e-3))
def test_continuity(theta, velocity, d_theta, d_velocity):
    # Torque is Lipschitz in elevation and velocity (no jumps at the blend or the floor).
    a = controller().step(0.0, theta, velocity).torque_nm
    b = controller().step(0.0, min(theta + d_theta, math.radians(140.0)), velocity + d_velocity).torque_nm
    assert abs(a - b) <= 20.0 * (d_theta + d_velocity)


@given(elevations, st.floats(-6.0, 5.9), st.floats(0.01, 0.1))
def test_more_torque_when_raising_faster(theta, velocity, dv):
    ctrl_a, ctrl_b = controller(), controller()
    assert ctrl_b.step(0.0, theta, velocity + dv).torque_nm >= ctrl_a.step(0.0, theta, velocity).torque_nm


def test_build_from_model_file(tmp_path):
    path = tmp_path / "model.json"
    save_model(MODEL, path)
    ctrl = build_controller(model=path, support="pretension", subject=SUBJECT)
    assert ctrl.model == MODEL
    assert ctrl.step(0.0, 1.0, 0.0).tension_n == 10.0
    with pytest.raises(ModelFileError):
        build_controller(model=tmp_path / "absent.json", support=0.5, subject=SUBJECT)
    with pytest.raises(ParameterError, match="support"):
        build_controller(model=MODEL, support=1.5, subject=SUBJECT)


@pytest.mark.parametrize(
    "kwargs",
    [{"min_torque_nm": -1.0}, {"max_torque_nm": 0.0}, {"max_tension_n": math.nan},
     {"elevation_min_rad": 2.0, "elevation_max_rad": 1.0}, {"nominal_period_s": 0.0}],
)
def test_invalid_limits(kwargs):
    with pytest.raises(ParameterError):
        ControllerLimits(**kwargs)
