"""The dynamic compensation's step: limits and faults as the paper's, its estimator, its reversal state."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bowden.control import ControllerLimits, Fault, build_controller
from bowden.errors import ParameterError
from bowden.model import CompensationLine, CompensationModel, Subject
from bowden.model.dynamic import DynamicCompensation
from bowden.model.elevation_estimator import estimator_gains
from bowden.sim import _batch_kernel as bk
from bowden.sim import _controller_kernel as ck

SUBJECT = Subject(height_m=1.75, mass_kg=70.0, sex="male")
DYNAMIC = DynamicCompensation(
    raising=CompensationLine(intercept_nm=0.08, slope_m=0.043),
    lowering=CompensationLine(intercept_nm=-0.08, slope_m=0.029),
    viscous_nm_s_rad=0.04,
    inertia_kg_m2=1.5e-3,
    imu_latency_s=0.04,
)
MODEL = CompensationModel(
    raising=CompensationLine(intercept_nm=0.11, slope_m=0.043),
    lowering=CompensationLine(intercept_nm=-0.11, slope_m=0.029),
    dynamic=DYNAMIC,
)


def movement(n: int, seed: int, *, noise: float = 1.0) -> list[tuple[float, float]]:
    """Elevation and gyro samples of raise-and-lower cycles with IMU-like noise."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        t = 0.002 * i
        phase = 2.0 * math.pi * t / 2.4
        elevation = math.radians(60.0 - 40.0 * math.cos(phase))
        velocity = math.radians(40.0) * 2.0 * math.pi / 2.4 * math.sin(phase)
        out.append((elevation + noise * rng.normal(0, 0.005), velocity + 0.01 + noise * rng.normal(0, 0.026)))
    return out


def test_the_model_recommends_its_dynamic_compensation_and_paper_forces_the_lines() -> None:
    assert build_controller(model=MODEL, support=0.5, subject=SUBJECT).compensation == "dynamic"
    assert (
        build_controller(model=MODEL, support=0.5, subject=SUBJECT, compensation="paper").compensation
        == "paper"
    )
    bare = replace(MODEL, dynamic=None)
    assert build_controller(model=bare, support=0.5, subject=SUBJECT).compensation == "paper"
    with pytest.raises(ParameterError, match="dynamic part"):
        build_controller(model=bare, support=0.5, subject=SUBJECT, compensation="dynamic")


def test_paper_compensation_is_unchanged_by_a_dynamic_part() -> None:
    """compensation="paper" on a version-2 model commands exactly what the lines alone command."""
    with_dynamic = build_controller(model=MODEL, support=0.5, subject=SUBJECT, compensation="paper")
    lines_only = build_controller(model=replace(MODEL, dynamic=None), support=0.5, subject=SUBJECT)
    for i, (elevation, velocity) in enumerate(movement(2000, 3)):
        assert with_dynamic.step(0.002 * i, elevation, velocity) == lines_only.step(
            0.002 * i, elevation, velocity
        )


@pytest.mark.parametrize("support", [0.5, "pretension"])
def test_compiled_dynamic_step_equals_the_closure(support: float | str) -> None:
    limits = ControllerLimits(max_torque_nm=3.0, max_torque_rate_nm_s=80.0)
    controller = build_controller(model=MODEL, support=support, subject=SUBJECT, limits=limits)  # type: ignore[arg-type]
    vector = bk.controller_vector(controller)
    assert vector[ck.C_DYNAMIC] == 1.0
    state = bk.controller_state(controller)
    out = np.zeros(5)
    rng = np.random.default_rng(5)
    for i, (elevation, velocity) in enumerate(movement(4000, 8)):
        t = 0.002 * i
        motor_velocity = rng.normal(0.0, 5.0) if i % 5 else math.nan
        if i in (1500, 1501):
            elevation = math.nan  # a fault: both restart the estimator
        if i == 2500:
            velocity = 30.0
        expected = controller.step(t, elevation, velocity, motor_velocity)
        bk.controller_step(vector, state, t, elevation, velocity, motor_velocity, math.nan, out)
        assert out[0] == pytest.approx(expected.torque_nm, abs=1e-12, rel=1e-12)
        if math.isnan(expected.tension_n):
            assert math.isnan(out[1])
        else:
            assert out[1] == pytest.approx(expected.tension_n, abs=1e-12, rel=1e-12)
        assert int(out[3]) == int(expected.faults)
        assert int(out[4]) == int(expected.limits)


class MatrixKalman:
    """The estimator in matrix form (x ← F·x; x ← x + K·(z − H·x)), written apart from the step: its
    white-jerk model (θ, θ̇, θ̈, gyro bias), gain and prediction across the latency, with numpy."""

    def __init__(self, period_s: float, latency_s: float) -> None:
        self.f = np.eye(4)
        self.f[0, 1], self.f[0, 2], self.f[1, 2] = period_s, 0.5 * period_s**2, period_s
        self.h = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 1.0]])
        self.k = np.array(estimator_gains(period_s, latency_s).gain)
        self.latency_s = latency_s
        self.x: np.ndarray | None = None

    def update(self, elevation: float, gyro: float) -> tuple[float, float, float, float]:
        """Predicted elevation, velocity and acceleration now, and the gyro bias."""
        z = np.array([elevation, gyro])
        if self.x is None:
            self.x = np.array([elevation, gyro, 0.0, 0.0])
        else:
            prior = self.f @ self.x
            self.x = prior + self.k @ (z - self.h @ prior)
        th, w, a, b = self.x
        lag = self.latency_s
        return th + w * lag + 0.5 * a * lag**2, w + a * lag, a, b


def test_the_step_predicts_the_elevation_of_the_matrix_form_filter() -> None:
    """The step's desired tension comes from the estimator's predicted elevation (pretension aside)."""
    estimator = MatrixKalman(0.002, DYNAMIC.imu_latency_s)
    controller = build_controller(model=MODEL, support=0.5, subject=SUBJECT)
    reference = build_controller(model=MODEL, support=0.5, subject=SUBJECT, compensation="paper")
    for i, (elevation, velocity) in enumerate(movement(1500, 2)):
        predicted, _, _, _ = estimator.update(elevation, velocity)
        command = controller.step(0.002 * i, elevation, velocity)
        assert command.tension_n == pytest.approx(
            reference.step(0.002 * i, predicted, 0.0).tension_n, rel=1e-9
        )


def test_estimator_learns_the_gyro_bias_at_rest_and_predicts_across_the_latency() -> None:
    """A biased gyro at rest, then a constant-acceleration arm seen 40 ms late: the prediction is the arm
    now (hand-derived: θ = θ₀ + a·t²/2), not where the IMU saw it."""
    latency, acceleration, bias = 0.04, 2.0, 0.05
    estimator = MatrixKalman(0.002, latency)
    for _ in range(10000):  # 20 s at rest
        *_, learnt_bias = estimator.update(0.3, bias)
    assert learnt_bias == pytest.approx(bias, abs=2e-3)
    for i in range(501):  # 1 s of motion starting at t = 0
        seen = max(0.002 * i - latency, 0.0)
        predicted, velocity, accel, _ = estimator.update(
            0.3 + 0.5 * acceleration * seen**2, acceleration * seen + bias
        )
    now = 1.0
    assert predicted == pytest.approx(0.3 + 0.5 * acceleration * now**2, abs=2e-3)
    assert velocity == pytest.approx(acceleration * now, abs=1e-2)
    assert accel == pytest.approx(acceleration, rel=0.05)
    # What the IMU shows at that moment is 80 mrad behind; the paper's step uses that.
    assert 0.3 + 0.5 * acceleration * (now - latency) ** 2 < predicted - 0.07


@settings(max_examples=25, deadline=None)
@given(
    gyro_noise=st.floats(0.0, 0.03),
    gyro_bias=st.floats(-0.02, 0.02),
    elevation_deg=st.floats(25.0, 110.0),
    seed=st.integers(0, 2**16),
)
def test_a_wearer_at_rest_with_a_noisy_gyro_never_toggles_the_command(
    gyro_noise: float, gyro_bias: float, elevation_deg: float, seed: int
) -> None:
    """At rest the reversal state holds: the command stays within a hair of its mean (no chattering),
    for gyro noise up to the NGIMU's 1.7°/s per sample and any small bias."""
    controller = build_controller(model=MODEL, support=0.5, subject=SUBJECT)
    rng = np.random.default_rng(seed)
    torques = []
    for i in range(3000):
        elevation = math.radians(elevation_deg) + rng.normal(0, 0.005)
        command = controller.step(0.002 * i, elevation, gyro_bias + gyro_noise * rng.normal())
        torques.append(command.torque_nm)
    settled = np.asarray(torques[500:])
    # The two lines differ by ≈ 0.5–1 Nm at these tensions; toggling between them would show as much.
    assert np.ptp(settled) < 0.05


@settings(max_examples=60, deadline=None)
@given(
    viscous=st.floats(0.0, 1.0),
    inertia=st.floats(0.0, 0.05),
    max_dynamic=st.floats(0.0, 5.0),
    seed=st.integers(0, 2**16),
)
def test_a_wrong_model_is_bounded(viscous: float, inertia: float, max_dynamic: float, seed: int) -> None:
    """Whatever the drag and inertia, the command stays within the motor limits and the dynamic bound."""
    dynamic = replace(DYNAMIC, viscous_nm_s_rad=viscous, inertia_kg_m2=inertia, max_dynamic_nm=max_dynamic)
    model = replace(MODEL, dynamic=dynamic)
    limits = ControllerLimits(max_torque_nm=4.0)
    controller = build_controller(model=model, support=0.5, subject=SUBJECT, limits=limits)
    lines = replace(model, dynamic=None)
    rng = np.random.default_rng(seed)
    for i, (elevation, velocity) in enumerate(movement(600, seed)):
        wild = velocity + rng.normal(0.0, 3.0)
        command = controller.step(0.002 * i, elevation, wild)
        assert 0.0 <= command.torque_nm <= 4.0
        assert command.faults == 0
        bound = max(lines.raising.torque_nm(command.tension_n), lines.lowering.torque_nm(command.tension_n))
        assert (
            command.torque_nm <= max(dynamic.raising.torque_nm(command.tension_n), bound) + max_dynamic + 1e-9
        )


def test_bad_inputs_fault_like_the_paper_step() -> None:
    controller = build_controller(model=MODEL, support=0.5, subject=SUBJECT)
    controller.step(0.0, 1.0, 0.0)
    command = controller.step(0.002, math.nan, 0.0)
    assert command.torque_nm == 0.0 and command.faults & Fault.NONFINITE_INPUT
    command = controller.step(0.004, 1.0, 40.0)
    assert command.torque_nm == 0.0 and command.faults & Fault.ELEVATION_VELOCITY_OUT_OF_RANGE
    assert controller.step(0.006, 1.0, 0.0).torque_nm <= 200.0 * 0.002 + 1e-12  # ramps up again


@pytest.mark.parametrize("compensation", ["paper", "dynamic"])
def test_the_specialised_step_is_the_generic_one_without_the_other_branches(compensation: str) -> None:
    """The controller runs step_closure's step with its parts spliced in and only its compensation's
    branches (control/step.py, _specialise): the same commands as the step that calls its parts, bit
    for bit, and none of the other's work."""
    from bowden.control.step import _PARTS, step_closure

    controller = build_controller(model=MODEL, support=0.5, subject=SUBJECT, compensation=compensation)  # type: ignore[arg-type]
    generic = step_closure(MODEL, compensation, controller.arm, controller.geometry,  # type: ignore[arg-type]
                           controller.assistance, controller.limits).step
    code = controller.step.__code__  # type: ignore[attr-defined]
    assert "dynamic" not in code.co_freevars and "dynamic" in generic.__code__.co_freevars  # type: ignore[attr-defined]
    assert ("e0" in code.co_varnames) == (compensation == "dynamic")  # the estimator's locals
    assert ("x" in code.co_varnames) == (compensation == "paper")  # the sigmoid's
    assert not set(code.co_names) & set(_PARTS)  # its parts spliced in: no call on the hot path
    assert set(generic.__code__.co_names) & set(_PARTS)  # type: ignore[attr-defined]
    for i, (elevation, velocity) in enumerate(movement(3000, 4)):
        if i == 1200:
            elevation = math.nan
        assert controller.step(0.002 * i, elevation, velocity) == generic(0.002 * i, elevation, velocity)
