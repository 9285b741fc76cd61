"""The AK family by name: each model's ranges as the manual prints them, and each model's driver
against its simulated peer over python-can's virtual bus (the bytes are real)."""

from __future__ import annotations

import time
from dataclasses import replace

import can
import pytest

from bowden.errors import ParameterError
from bowden.hardware.ak60 import AK60Config, AK60Motor
from bowden.hardware.ak60_codec import GAIN_BITS, TORQUE_BITS, AK60Limits
from bowden.hardware.motors import AK_MOTORS, FIRMWARE_VARIANTS, motor_limits, motor_model
from bowden.hardware.protocols import MotorState
from bowden.sim.peers import AK60Peer, WallTimePlant
from bowden.sim.peers.ak60_peer import COMMAND

# CubeMars "AK Series Actuator Driver Manual" V1.0.8 §5.3, p. 50 (velocity rad/s, torque Nm), typed
# in from the manual rather than read from the code under test.
MANUAL_V108 = {
    "AK10-9": (50.0, 65.0),
    "AK60-6": (45.0, 15.0),
    "AK70-10": (50.0, 25.0),
    "AK80-6": (76.0, 12.0),
    "AK80-9": (50.0, 18.0),
    "AK80-64": (8.0, 144.0),
}
FAST = AK60Config(reply_timeout_s=0.05, special_reply_timeout_s=1.0, zero_settle_s=0.02, zero_timeout_s=5.0)


def exchange(motor: AK60Motor, torque_nm: float, timeout_s: float = 2.0) -> MotorState:
    """One torque command and the reply to it (the test waits, not the driver)."""
    while motor.poll(0.005) is not None:
        pass
    state = motor.command_torque(torque_nm)
    deadline = time.monotonic() + timeout_s
    while state is None and time.monotonic() < deadline:
        state = motor.poll(0.01)
    assert state is not None, "no reply"
    return state


def step_nm(limits: AK60Limits) -> float:
    return 2.0 * limits.torque_nm / ((1 << TORQUE_BITS) - 1)


@pytest.mark.parametrize("name", sorted(MANUAL_V108))
def test_each_model_has_the_manuals_ranges(name: str) -> None:
    limits = motor_limits(name)
    assert (limits.velocity_rad_s, limits.torque_nm) == MANUAL_V108[name]
    assert (limits.position_rad, limits.kp_max, limits.kd_max) == (12.5, 500.0, 5.0)
    # The gear ratio is the number after the dash (CubeMars' naming), the AK80-64's included.
    assert motor_model(name).gear_ratio == float(name.split("-")[1])


def test_the_catalogue_lists_exactly_the_issues_models() -> None:
    assert set(AK_MOTORS) == set(MANUAL_V108)
    assert "peak-9nm" in FIRMWARE_VARIANTS and "manual-v1.0.8" in FIRMWARE_VARIANTS
    assert motor_model("AK70-10").output_torque_constant_nm_per_a == pytest.approx(0.95)


def test_unknown_models_and_variants_are_refused_naming_the_flags() -> None:
    with pytest.raises(ParameterError, match=r"--motor AK99-1 is not a known motor; known: AK10-9"):
        motor_model("AK99-1")
    # peak-9nm is an AK60-6 variant only: another model with it is a configuration error.
    with pytest.raises(ParameterError, match=r"--firmware peak-9nm is not a firmware variant of the AK70-10"):
        motor_limits("AK70-10", "peak-9nm")


@pytest.mark.parametrize("name", sorted(MANUAL_V108))
def test_each_model_against_its_simulated_peer(name: str, can_buses: tuple[can.BusABC, can.BusABC],
                                               wall_plant: WallTimePlant) -> None:
    limits = motor_limits(name)
    # 80 % of the model's own torque range: beyond the AK60-6's ±15 Nm for every model but the
    # AK80-6, so a driver or peer still on the AK60-6's ranges would clamp or rescale it.
    torque_nm = 0.8 * limits.torque_nm
    with AK60Peer(can_buses[1], wall_plant, limits=limits, zero_silence_s=0.05) as peer:
        motor = AK60Motor(can_buses[0], replace(FAST, limits=limits, torque_limit_nm=limits.torque_nm))
        motor.enable()
        state = exchange(motor, torque_nm)
        commands = [frame for frame in peer.received if frame.kind == COMMAND]
        assert commands[-1].torque_nm == pytest.approx(torque_nm, abs=step_nm(limits))
        # The reply is decoded at the model's ranges too: the torque the peer reported, not a rescaled one.
        assert abs(state.torque_nm) <= limits.torque_nm
        motor.disable()
        assert not peer.in_motor_mode


def test_a_driver_on_another_models_ranges_rescales_every_command(
        can_buses: tuple[can.BusABC, can.BusABC], wall_plant: WallTimePlant) -> None:
    # Why --motor matters: an AK70-10 driven with the AK60-6's ranges gets 25/15 of every torque.
    with AK60Peer(can_buses[1], wall_plant, limits=motor_limits("AK70-10"), zero_silence_s=0.05) as peer:
        motor = AK60Motor(can_buses[0], replace(FAST, limits=motor_limits("AK60-6")))
        motor.enable()
        exchange(motor, 6.0)
        assert peer.received[-1].torque_nm == pytest.approx(6.0 * 25.0 / 15.0, abs=50.0 / 4095)
        motor.disable()


def test_gain_fields_are_the_same_on_every_model() -> None:
    # Kp and Kd are 12-bit fields over 0–500 and 0–5 for every model (manual V1.0.8 §5.3).
    assert GAIN_BITS == 12
    assert {(m.limits().kp_max, m.limits().kd_max) for m in AK_MOTORS.values()} == {(500.0, 5.0)}
