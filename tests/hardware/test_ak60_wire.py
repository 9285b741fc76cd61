"""The AK60-6 driver against the simulated motor over python-can's virtual bus: the bytes are real.

The driver never waits for a reply in a torque command (the reply of one cycle serves the next), so
the tests that need the answer to one particular command use :func:`exchange`: older replies are
taken first, then the command goes out and the test waits (not the driver) for its reply. The
control-cycle contract itself (never blocking, bounded reads, the reply filter, leaving on a dead bus)
is tested in ``test_ak60_cycle.py``.

Waits for an answer that must come are generous (they only keep a broken driver from hanging); a
verdict never depends on how fast the machine is.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import can
import pytest

from bowden.errors import DeviceTimeoutError, ParameterError, TransmitError
from bowden.hardware.ak60 import ERRNO_NO_BUFFER_SPACE, AK60Config, AK60Motor
from bowden.hardware.ak60_codec import FIRMWARE_LIMITS, MotorErrorCode, position_resolution_rad
from bowden.hardware.protocols import Motor, MotorState
from bowden.sim.peers import AK60Peer, WallTimePlant
from bowden.sim.peers.ak60_peer import COMMAND, ENTER, EXIT, ZERO

if TYPE_CHECKING:
    from conftest import SimplePlant

FAST = AK60Config(reply_timeout_s=0.05, special_reply_timeout_s=1.0, zero_settle_s=0.02, zero_timeout_s=5.0)


def exchange(motor: AK60Motor, torque_nm: float, timeout_s: float = 2.0) -> MotorState:
    """Send one torque command and wait (here, not in the driver) for the reply to it."""
    while motor.poll(0.005) is not None:  # replies to earlier commands
        pass
    state = motor.command_torque(torque_nm)
    deadline = time.monotonic() + timeout_s
    while state is None and time.monotonic() < deadline:
        state = motor.poll(0.01)
    assert state is not None, "no reply"
    return state


def run_for(motor: AK60Motor, torque_nm: float, cycles: int) -> MotorState:
    """Command ``torque_nm`` every 2 ms for ``cycles`` cycles, like the loop; the last reply."""
    for _ in range(cycles):
        motor.command_torque(torque_nm)
        time.sleep(0.002)
    return exchange(motor, torque_nm)


@pytest.fixture
def peer(can_buses: tuple[can.BusABC, can.BusABC], wall_plant: WallTimePlant) -> Iterator[AK60Peer]:
    with AK60Peer(can_buses[1], wall_plant, zero_silence_s=0.05) as running:
        yield running


@pytest.fixture
def motor(can_buses: tuple[can.BusABC, can.BusABC], peer: AK60Peer) -> AK60Motor:
    return AK60Motor(can_buses[0], FAST)


def test_driver_implements_the_motor_protocol(motor: AK60Motor) -> None:
    assert isinstance(motor, Motor)


def test_enter_command_reply_exit(motor: AK60Motor, peer: AK60Peer, plant: SimplePlant) -> None:
    state = motor.enable()
    assert peer.in_motor_mode and motor.enabled
    assert state.error_code == 0 and state.temperature_c == plant.motor.temperature_c
    state = run_for(motor, 2.0, 100)
    commands = [frame for frame in peer.received if frame.kind == COMMAND]
    # The peer decoded the driver's bytes to the torque asked for (within one 12-bit step of ±15 Nm).
    assert commands[-1].torque_nm == pytest.approx(2.0, abs=30.0 / 4095)
    # The reply carries the plant's state: torque lagging towards 2 Nm, spool accelerating.
    assert state.torque_nm == pytest.approx(plant.motor.torque_nm, abs=0.02)
    assert state.velocity_rad_s > 0.0
    motor.disable()
    assert not peer.in_motor_mode and not motor.enabled
    assert peer.received[0].kind == ENTER
    assert peer.received[-1].kind == EXIT
    # Outside motor mode the motor answers but applies no torque.
    exchange(motor, 3.0)
    assert peer.received[-1].torque_nm == 0.0
    motor.disable()  # twice is fine


def test_negative_direction_flips_every_sign(can_buses: tuple[can.BusABC, can.BusABC], peer: AK60Peer,
                                             plant: SimplePlant) -> None:
    motor = AK60Motor(can_buses[0], replace(FAST, direction=-1))
    motor.enable()
    state = run_for(motor, 1.0, 50)
    assert peer.received[-1].torque_nm == pytest.approx(-1.0, abs=30.0 / 4095)
    assert plant.motor.velocity_rad_s < 0.0 < state.velocity_rad_s
    assert state.torque_nm > 0.0
    motor.disable()


def test_torque_is_clamped_to_the_configured_limit(motor: AK60Motor, peer: AK60Peer) -> None:
    motor.enable()
    exchange(motor, 50.0)
    assert peer.received[-1].torque_nm == pytest.approx(9.0, abs=30.0 / 4095)
    with pytest.raises(ParameterError, match="NaN"):
        motor.command_torque(math.nan)
    motor.disable()


def test_set_zero_waits_out_the_silence(motor: AK60Motor, peer: AK60Peer, plant: SimplePlant) -> None:
    motor.enable()
    state = run_for(motor, 1.0, 150)
    exchange(motor, 0.0)
    plant.motor.damping_nm_s = 10.0  # stop the spool so the zero is well defined
    assert abs(state.position_rad) > 0.05
    motor.set_zero()
    assert any(frame.kind == ZERO for frame in peer.received)
    after = exchange(motor, 0.0)
    assert after.position_rad == pytest.approx(0.0, abs=0.01)
    motor.disable()


def test_set_zero_times_out_on_a_motor_that_stays_silent(can_buses: tuple[can.BusABC, can.BusABC],
                                                          wall_plant: WallTimePlant) -> None:
    config = AK60Config(reply_timeout_s=0.01, zero_settle_s=0.01, zero_timeout_s=0.1)
    with AK60Peer(can_buses[1], wall_plant, zero_silence_s=5.0):
        motor = AK60Motor(can_buses[0], config)
        with pytest.raises(DeviceTimeoutError, match="set-zero"):
            motor.set_zero()


def test_enable_times_out_without_a_motor(can_buses: tuple[can.BusABC, can.BusABC]) -> None:
    motor = AK60Motor(can_buses[0], AK60Config(special_reply_timeout_s=0.02))
    with pytest.raises(DeviceTimeoutError, match="enter motor mode"):
        motor.enable()
    assert not motor.enabled


def test_enter_motor_mode_is_sent_again_when_a_frame_is_lost(can_buses: tuple[can.BusABC, can.BusABC],
                                                             peer: AK60Peer,
                                                             caplog: pytest.LogCaptureFixture) -> None:
    config = replace(FAST, special_reply_timeout_s=0.5)  # each lost attempt costs this long
    motor = AK60Motor(can_buses[0], config)
    peer.ignore_next(config.enter_attempts - 1)  # lost on the bus: every attempt but the last
    state = motor.enable()
    assert motor.enabled and peer.in_motor_mode and state.error_code == 0
    assert [frame.kind for frame in peer.received] == [ENTER]  # the lost ones never arrived
    assert sum("sending it again" in r.getMessage() for r in caplog.records) == config.enter_attempts - 1
    motor.disable()


def test_enable_gives_up_after_its_attempts(can_buses: tuple[can.BusABC, can.BusABC], peer: AK60Peer) -> None:
    motor = AK60Motor(can_buses[0], replace(FAST, special_reply_timeout_s=0.05))
    peer.ignore_next(motor.config.enter_attempts)
    with pytest.raises(DeviceTimeoutError, match="enter motor mode"):
        motor.enable()
    assert not motor.enabled and not peer.in_motor_mode


@pytest.mark.parametrize("code", [c for c in MotorErrorCode if c != MotorErrorCode.NONE])
def test_each_motor_error_code_surfaces_in_the_state(motor: AK60Motor, peer: AK60Peer,
                                                      code: MotorErrorCode) -> None:
    motor.enable()
    peer.inject_error(int(code))
    state = exchange(motor, 0.5)
    assert state.error_code == code
    peer.inject_error(0)
    assert exchange(motor, 0.0).error_code == 0
    motor.disable()


def test_six_byte_firmware(can_buses: tuple[can.BusABC, can.BusABC], wall_plant: WallTimePlant) -> None:
    with AK60Peer(can_buses[1], wall_plant, reply_length=6):
        motor = AK60Motor(can_buses[0], FAST)
        state = motor.enable()
        assert math.isnan(state.temperature_c) and state.error_code == 0
        motor.disable()


def test_other_firmware_variant_end_to_end(can_buses: tuple[can.BusABC, can.BusABC],
                                           wall_plant: WallTimePlant) -> None:
    limits = FIRMWARE_LIMITS["peak-9nm"]
    with AK60Peer(can_buses[1], wall_plant, limits=limits) as peer:
        motor = AK60Motor(can_buses[0], replace(FAST, limits=limits))
        motor.enable()
        exchange(motor, 4.0)
        assert peer.received[-1].torque_nm == pytest.approx(4.0, abs=18.0 / 4095)
        motor.disable()


def test_bad_and_foreign_frames_never_end_the_wait_for_a_good_one(motor: AK60Motor, peer: AK60Peer) -> None:
    motor.enable()
    # Just before its reply the motor's end of the bus carries: a reply with the right ids but the wrong
    # length (malformed), then frames that are not this motor's replies — another motor's, another
    # node's carrying our id in byte 0 on another CAN id, an extended id, a remote frame.
    peer.precede_next_reply([
        can.Message(arbitration_id=0, data=bytes([1, 0x80, 0x00]), is_extended_id=False),
        can.Message(arbitration_id=0, data=bytes([7, 1, 2, 3, 4, 5, 6, 7]), is_extended_id=False),
        can.Message(arbitration_id=0x123, data=bytes([1, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0, 0]),
                    is_extended_id=False),
        can.Message(arbitration_id=0, data=bytes([1, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0, 0]),
                    is_extended_id=True),
        can.Message(arbitration_id=0, is_remote_frame=True, dlc=8, is_extended_id=False),
    ])
    foreign_before = motor.counters.foreign
    state = exchange(motor, 0.5)
    # The reply behind them is taken, whatever poll met them first; none of them is.
    assert state.error_code == 0 and abs(state.position_rad) < 1.0
    assert motor.counters.malformed == 1 and motor.last_malformed is None
    assert motor.counters.foreign - foreign_before == 4
    motor.disable()


def test_a_flood_is_taken_a_bounded_number_of_frames_at_a_time(motor: AK60Motor, peer: AK60Peer,
                                                                can_buses: tuple[can.BusABC, can.BusABC]
                                                                ) -> None:
    motor.enable()
    exchange(motor, 0.0)
    flood = can.Message(arbitration_id=0x555, data=bytes([1, 2, 3, 4, 5, 6, 7, 8]), is_extended_id=False)
    for _ in range(10_000):
        can_buses[1].send(flood)
    before = motor.counters.foreign
    motor.command_torque(0.0)
    assert motor.counters.foreign - before <= motor.config.max_frames_per_poll
    assert motor.counters.poll_limit_hits >= 1
    motor.disable()


def test_replies_on_another_id_are_named_when_enable_fails(can_buses: tuple[can.BusABC, can.BusABC],
                                                           wall_plant: WallTimePlant) -> None:
    with AK60Peer(can_buses[1], wall_plant, reply_arbitration_id=0x10):
        # The driver's time passes only once the motor's frame has come (on the wrong id): its wait
        # ends after that, however slow the machine.
        motor: AK60Motor

        def clock() -> float:
            return 1.0 if motor.counters.foreign else 0.0

        motor = AK60Motor(can_buses[0], AK60Config(special_reply_timeout_s=0.5, enter_attempts=1),
                          clock=clock)
        with pytest.raises(DeviceTimeoutError, match="CAN id 0x10"):
            motor.enable()
        relaxed = AK60Motor(can_buses[0], replace(FAST, reply_arbitration_id=0x10))
        assert relaxed.enable().error_code == 0
        relaxed.disable()


def test_wraps_are_counted_over_many_turns(motor: AK60Motor, peer: AK60Peer, plant: SimplePlant) -> None:
    # The plant stands still (no torque) and the test moves the spool by hand, 0.3 rad at a time,
    # out to 8 output turns and back: the ±12.5 rad field wraps twice on the way out.
    motor.enable()
    # Held in place: the +½-step "zero" torque (zero is not on the 12-bit grid) must not move it between
    # the test's setting and the reply, however long that takes on a busy machine.
    plant.motor.inertia_kg_m2 = 1e12
    targets = [0.3 * k for k in range(168)] + [0.3 * k for k in range(167, -60, -1)]
    lsb = position_resolution_rad(motor.config.limits)
    for target in targets:
        plant.motor.position_rad = target
        plant.motor.velocity_rad_s = 0.0
        state = exchange(motor, 0.0)
        assert state.position_rad == pytest.approx(target, abs=lsb)
    motor.disable()


def test_context_manager_leaves_the_motor_safe(can_buses: tuple[can.BusABC, can.BusABC],
                                               peer: AK60Peer) -> None:
    with pytest.raises(RuntimeError, match="boom"), AK60Motor(can_buses[0], FAST) as motor:
        motor.enable()
        exchange(motor, 2.0)
        raise RuntimeError("boom")
    kinds = [frame.kind for frame in peer.received]
    assert kinds[-1] == EXIT
    # Zero is not on the grid of a symmetric 12-bit field: it goes out as +½ step (3.7 mNm at ±15 Nm),
    # which is why the safe state ends by leaving motor mode, not with a zero command.
    assert peer.received[-2].kind == COMMAND
    assert peer.received[-2].torque_nm == pytest.approx(0.0, abs=15.0 / 4095)
    assert not peer.in_motor_mode


class FlakyBus(can.BusABC):
    """A bus whose first ``failures`` sends fail like socketcan with nothing on the bus to ACK."""

    def __init__(self, inner: can.BusABC, failures: int) -> None:
        super().__init__(channel="flaky")
        self.inner = inner
        self.failures = failures
        self.attempts = 0

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.attempts += 1
        if self.failures > 0:
            self.failures -= 1
            raise can.CanOperationError("Failed to transmit: No buffer space available",
                                        error_code=ERRNO_NO_BUFFER_SPACE)
        self.inner.send(msg, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return self.inner.recv(timeout), True

    def shutdown(self) -> None:
        super().shutdown()


def test_transient_transmit_failure_is_retried(can_buses: tuple[can.BusABC, can.BusABC],
                                               peer: AK60Peer) -> None:
    bus = FlakyBus(can_buses[0], failures=1)
    try:
        motor = AK60Motor(bus, FAST)
        motor.enable()
        assert motor.counters.transmit_retries == 1 and motor.counters.transmit_failures == 0
        motor.disable()
    finally:
        bus.shutdown()


def test_persistent_transmit_failure_raises_with_a_hint(can_buses: tuple[can.BusABC, can.BusABC]) -> None:
    bus = FlakyBus(can_buses[0], failures=100)
    try:
        motor = AK60Motor(bus, AK60Config(send_attempts=3))
        with pytest.raises(TransmitError, match="no buffer space") as info:
            motor.enable()
        assert isinstance(info.value, OSError)
        assert bus.attempts == 3 and motor.counters.transmit_failures == 1
    finally:
        bus.shutdown()


def test_a_failed_send_in_the_cycle_raises_at_once(can_buses: tuple[can.BusABC, can.BusABC],
                                                   peer: AK60Peer) -> None:
    bus = FlakyBus(can_buses[0], failures=0)
    try:
        motor = AK60Motor(bus, FAST)
        motor.enable()
        bus.failures = 100
        attempts = bus.attempts
        with pytest.raises(TransmitError, match="no buffer space"):
            motor.command_torque(1.0)
        assert bus.attempts - attempts == 1  # no retry, no sleep in the cycle
        # Leaving the block on a dead bus is said (exit_error), never raised.
        motor.__exit__(None, None, None)
        assert motor.exit_error is not None and "no buffer space" in motor.exit_error
    finally:
        bus.shutdown()


def test_config_validation_names_the_field() -> None:
    bad: list[dict[str, Any]] = [
        {"motor_id": 0}, {"reply_timeout_s": 0.0}, {"direction": 2}, {"kd": 6.0},
        {"zero_settle_s": 3.0}, {"send_attempts": 0}, {"reply_arbitration_id": 0x800},
        {"reply_wait_s": 0.01}, {"max_frames_per_poll": 0},
    ]
    for kwargs in bad:
        with pytest.raises(ParameterError, match=next(iter(kwargs))):
            AK60Config(**kwargs)
