"""``bowden run --backend sim``: the simulated suit behind its wire peers, driven by the real drivers.

By default the suit runs in a process of its own (:mod:`bowden.sim.link.suit_process`) and the
loop's process talks to it as to the real suit: the AK60-6 driver over a CAN bus that crosses
processes (``bowden_loopback``), the NGIMU client over loopback UDP, the ADS1115 reader over an I²C
link. A stall of the loop's process is then seen by the devices as it would be on the suit.
``in_process=True`` keeps the peers as threads of the loop's process on python-can's ``virtual``
bus (quick tests); batch simulation (``bowden study``) uses neither, it runs the plant directly.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from typing import TYPE_CHECKING, Any

from bowden.contracts import SPEED_PEAK_DEG_S
from bowden.hardware.backend import Backend
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.sim.arm_follower import ArmFollowingTheLoop, FollowedReference

if TYPE_CHECKING:
    from bowden.hardware.ak60 import AK60Config

_channels = itertools.count()


class _RecordedReference:
    """The loop's ``reference_elevation``: the reference at loop time; its first call ties the arm."""

    def __init__(self, reference: FollowedReference, tie: Callable[[float], None]) -> None:
        self.reference = reference
        self._tie: Callable[[float], None] | None = tie

    def __call__(self, time_s: float) -> float:
        if self._tie is not None:
            tie, self._tie = self._tie, None
            tie(time.monotonic() - time_s)  # the loop's clock is time.monotonic (MonotonicClock)
        return self.reference.elevation_rad(time_s)


@contextmanager
def open_sim_backend(
    *, speed: str = "V1", reference: FollowedReference | None = None, calibration_s: float = 0.3,
    in_process: bool = False, announce: Callable[[str], None] | None = None,
    motor: str = "AK60-6", firmware: str | None = None, motor_id: int = 1,
    imu_lsl_name: str | None = None,
) -> Iterator[Backend]:
    """The simulated suit behind its wire peers, driven by the real drivers (all closed on exit).

    Parameters
    ----------
    speed
        Without ``reference``: the arm repeats the paper's cycle at this speed from the start.
    reference
        The arm follows this reference instead (lead-in, repetitions, rest), as a participant
        following the display would; it is also what the recording's reference column holds.
    calibration_s
        The simulated arm-down calibration.
    in_process
        Run the device peers as threads of this process (quick tests) instead of a process of their own.
    announce
        Told about a slow start (a first run compiles the simulated suit).
    motor, firmware
        The AK-series model and firmware variant (``bowden.hardware.motors``): the simulated TDU
        speaks its MIT-mode ranges, and the driver is set up for them.
    motor_id
        The id the *driver* expects (``--motor-id``); the simulated motor answers on id 1, so another
        id hears no reply, as on the real bus.
    imu_lsl_name
        The simulated IMU publishes an LSL quaternion stream of this name, read by
        :class:`~bowden.hardware.lsl_imu.LslImuClient` (``--imu lsl:NAME``), instead of NGIMU OSC.
    """
    from bowden.hardware.ak60 import AK60Config
    from bowden.hardware.motors import motor_model

    limits = motor_model(motor).limits(firmware)
    config = AK60Config(motor_id=motor_id, limits=limits)
    if motor != "AK60-6":  # another model is clamped at its field's range (cli._suit.motor_config)
        config = AK60Config(motor_id=motor_id, limits=limits, torque_limit_nm=limits.torque_nm)
    cycle = MinimumJerkCycle(peak_speed_rad_s=math.radians(SPEED_PEAK_DEG_S[speed]))
    opener = _in_process if in_process else _own_process
    with opener(cycle, reference, calibration_s, announce, config, imu_lsl_name) as backend:
        backend.describe = f"{motor} ({limits.velocity_rad_s:g} rad/s, {limits.torque_nm:g} Nm ranges) " \
                           f"on the {backend.describe}"
        yield backend


@contextmanager
def _own_process(cycle: MinimumJerkCycle, reference: FollowedReference | None, calibration_s: float,
                 announce: Callable[[str], None] | None, config: AK60Config,
                 imu_lsl_name: str | None = None) -> Iterator[Backend]:
    import can

    from bowden.hardware.ads1115 import ADS1115Config, ADS1115LoadCell, LoadCellCalibration
    from bowden.hardware.ak60 import AK60Motor
    from bowden.hardware.ngimu import NgimuClient, NgimuConfig
    from bowden.runtime.clock import MonotonicClock
    from bowden.sim.link.i2c import RemoteSMBus
    from bowden.sim.link.suit_process import SimulatedSuitProcess

    with ExitStack() as stack:
        ngimu = stack.enter_context(NgimuClient(NgimuConfig(host="127.0.0.1", port=0)))
        suit = SimulatedSuitProcess(imu_target=ngimu.address, reference=reference,
                                    cycle=cycle if reference is None else None, motor_limits=config.limits,
                                    imu_lsl_name=imu_lsl_name)
        stack.enter_context(suit.start(announce))
        imu: Any = ngimu
        if imu_lsl_name is not None:  # the child publishes the stream now
            from bowden.hardware.lsl_imu import LslImuClient, LslImuConfig

            imu = stack.enter_context(LslImuClient(LslImuConfig(stream_name=imu_lsl_name)))
        bus = stack.enter_context(can.Bus(interface="bowden_loopback", channel=suit.can_channel))
        smbus = stack.enter_context(RemoteSMBus(suit.i2c_path))
        calibration = LoadCellCalibration(offset_v=0.05, gain_n_per_v=100.0)
        load_cell = stack.enter_context(ADS1115LoadCell(smbus, ADS1115Config(data_rate=6),
                                                        calibration=calibration))
        suit.hold_arm_down()  # the participant stands with the arm hanging for the calibration
        imu.calibrate_arm_down(calibration_s)
        suit.hold_arm_down(False)
        origin = suit.start_plant()
        recorded: Callable[[float], float]
        if reference is not None:
            recorded = _RecordedReference(reference, suit.loop_started)
        else:
            def recorded(t: float) -> float:
                # Plant time of loop time t: the loop's clock and the plant's are both time.monotonic.
                return float(cycle.elevation_rad(time.monotonic() - origin))

        yield Backend(
            motor=stack.enter_context(AK60Motor(bus, config)),
            imu=imu, clock=MonotonicClock(), load_cell=load_cell, reference_elevation=recorded,
            describe=f"simulated suit in its own process (pid {suit.pid}): CAN over bowden_loopback, "
                     + (f"OSC on {ngimu.address[0]}:{ngimu.address[1]}" if imu is ngimu else imu.source)
                     + ", I²C over a local socket",
            inject=suit.inject, simulation=suit,
        )


@contextmanager
def open_sim_bench(*, calibration_s: float = 0.3, announce: Callable[[str], None] | None = None,
                   mannequin_id: int = 2, mannequin_motor: str = "AK80-9",
                   mannequin_direction: int = 1, motor: str = "AK60-6",
                   firmware: str | None = None) -> Iterator[Backend]:
    """The simulated mannequin bench in its own process, behind its wire peers: the TDU (AK60-6, CAN
    id 1) and the mannequin's motor (AK80-9, id 2) on one CAN bus, the NGIMU on the mannequin's arm,
    the ADS1115 load cell; driven by the real drivers of this process (``Backend.mannequin`` is the
    second motor). Everything is closed on exit; the drivers leave motor mode first.

    ``mannequin_id``, ``mannequin_motor`` and ``mannequin_direction`` configure the mannequin's
    *driver* (``bowden bench run``'s options), not the simulated motor: a driver set up for another
    id hears no reply, as on the real bus. ``motor`` and ``firmware`` name the TDU's AK model
    (``--motor``, ``--firmware``): the simulated TDU speaks its ranges and its driver expects them."""
    import can

    from bowden.hardware.ads1115 import ADS1115Config, ADS1115LoadCell, LoadCellCalibration
    from bowden.hardware.ak60 import AK60Config, AK60Motor
    from bowden.hardware.ak60_codec import limits_for_motor
    from bowden.hardware.ngimu import NgimuClient, NgimuConfig
    from bowden.runtime.clock import MonotonicClock
    from bowden.sim.link.i2c import RemoteSMBus
    from bowden.sim.link.suit_process import MANNEQUIN_MOTOR_ID, SimulatedSuitProcess

    with ExitStack() as stack:
        imu = stack.enter_context(NgimuClient(NgimuConfig(host="127.0.0.1", port=0)))
        from bowden.hardware.motors import motor_model

        tdu_limits = motor_model(motor).limits(firmware)
        tdu_config = AK60Config(limits=tdu_limits) if motor == "AK60-6" else \
            AK60Config(limits=tdu_limits, torque_limit_nm=tdu_limits.torque_nm)
        suit = SimulatedSuitProcess(imu_target=imu.address, bench=True, motor_limits=tdu_limits)
        stack.enter_context(suit.start(announce))
        tdu_bus = stack.enter_context(can.Bus(interface="bowden_loopback", channel=suit.can_channel))
        mannequin_bus = stack.enter_context(can.Bus(interface="bowden_loopback", channel=suit.can_channel))
        smbus = stack.enter_context(RemoteSMBus(suit.i2c_path))
        calibration = LoadCellCalibration(offset_v=0.05, gain_n_per_v=100.0)
        load_cell = stack.enter_context(ADS1115LoadCell(smbus, ADS1115Config(data_rate=6),
                                                        calibration=calibration))
        suit.hold_arm_down()
        imu.calibrate_arm_down(calibration_s)
        suit.hold_arm_down(False)
        suit.start_plant()
        limits = limits_for_motor(mannequin_motor)
        mannequin_config = AK60Config(motor_id=mannequin_id, limits=limits, direction=mannequin_direction,
                                      torque_limit_nm=limits.torque_nm)
        yield Backend(
            motor=stack.enter_context(AK60Motor(tdu_bus, tdu_config)),
            mannequin=stack.enter_context(AK60Motor(mannequin_bus, mannequin_config)),
            imu=imu, clock=MonotonicClock(), load_cell=load_cell,
            describe=f"simulated mannequin bench in its own process (pid {suit.pid}): TDU id 1 and "
                     f"mannequin id {MANNEQUIN_MOTOR_ID} (driven as id {mannequin_id}) over bowden_loopback, "
                     f"OSC on "
                     f"{imu.address[0]}:{imu.address[1]}, I²C over a local socket",
            inject=suit.inject, simulation=suit,
        )


@contextmanager
def _in_process(cycle: MinimumJerkCycle, reference: FollowedReference | None, calibration_s: float,
                announce: Callable[[str], None] | None, config: AK60Config,
                imu_lsl_name: str | None = None) -> Iterator[Backend]:
    import can

    from bowden.hardware.ads1115 import ADS1115Config, ADS1115LoadCell, LoadCellCalibration
    from bowden.hardware.ak60 import AK60Motor
    from bowden.hardware.ngimu import NgimuClient, NgimuConfig
    from bowden.runtime.clock import MonotonicClock
    from bowden.sim.arm import PrescribedArm
    from bowden.sim.peers import ADS1115Peer, AK60Peer, FakeSMBus, NgimuPeer, WallTimePlant
    from bowden.sim.peers.warm_up import warm_up_suit
    from bowden.sim.suit import SimulatedSuit

    warm_up_suit(PrescribedArm.following(cycle))  # the first frames must not wait for a compile
    follower = ArmFollowingTheLoop(reference) if reference is not None else None
    arm = follower.arm() if follower is not None else PrescribedArm.following(cycle)
    plant = WallTimePlant(SimulatedSuit(arm=arm))
    channel = f"bowden-sim-{next(_channels)}"
    with ExitStack() as stack:
        driver_bus = stack.enter_context(can.Bus(interface="virtual", channel=channel))
        peer_bus = stack.enter_context(can.Bus(interface="virtual", channel=channel))
        motor_peer = stack.enter_context(AK60Peer(peer_bus, plant, limits=config.limits))
        imu: Any
        if imu_lsl_name is not None:
            from bowden.hardware.lsl_imu import LslImuClient, LslImuConfig
            from bowden.sim.peers.lsl_imu_peer import LslImuPeer

            imu_peer: NgimuPeer = stack.enter_context(LslImuPeer(plant, imu_lsl_name, rate_hz=200.0))
            imu = stack.enter_context(LslImuClient(LslImuConfig(stream_name=imu_lsl_name)))
        else:
            imu = stack.enter_context(NgimuClient(NgimuConfig(host="127.0.0.1", port=0)))
            imu_peer = stack.enter_context(NgimuPeer(plant, imu.address, rate_hz=200.0))
        adc = ADS1115Peer(plant, offset_v=0.05, volts_per_newton=0.01)
        smbus = stack.enter_context(FakeSMBus(adc))
        calibration = LoadCellCalibration(offset_v=0.05, gain_n_per_v=100.0)
        load_cell = stack.enter_context(
            ADS1115LoadCell(smbus, ADS1115Config(data_rate=6), calibration=calibration)
        )
        imu_peer.hold_arm_down()
        imu_peer.wait_until_sent()  # nothing sent before the hold reaches the calibration
        imu.calibrate_arm_down(calibration_s)
        imu_peer.hold_arm_down(False)
        plant.start()
        recorded: Callable[[float], float]
        if follower is not None:
            follower.plant = plant

            def tie(monotonic_s: float) -> None:
                follower.plant_time_at_loop_start_s = monotonic_s - plant.origin_s

            recorded = _RecordedReference(follower.reference, tie)
        else:
            offset = plant.origin_s

            def recorded(t: float) -> float:
                return float(cycle.elevation_rad(time.monotonic() - offset))

        devices: dict[str, Any] = {"motor": motor_peer, "imu": imu_peer, "adc": adc}

        def inject(target: str, method: str, *args: Any) -> Any:
            return getattr(devices[target], method)(*args)

        yield Backend(
            motor=stack.enter_context(AK60Motor(driver_bus, config)),
            imu=imu, clock=MonotonicClock(), load_cell=load_cell, reference_elevation=recorded,
            describe=f"simulated suit in this process over virtual CAN {channel}, "
                     f"{getattr(imu, 'source', '') or f'OSC on {imu.address}'}, fake I²C",
            inject=inject,
        )

