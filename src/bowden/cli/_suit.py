"""The suit that ``bowden run`` and ``bowden serve`` drive: its command-line options and how it opens.

One place for both commands: the real suit's options (AK60-6 over CAN, NGIMU over OSC/UDP, optional
ADS1115 load cell) as a validated :class:`CanSuitOptions`, the ``argparse`` group that fills it, and
two context managers that open a suit and close it safely — :func:`open_can_backend` (the real
devices) and :func:`open_sim_backend` (the simulated suit behind peers that speak the same wire
protocols, driven by the same drivers). Both yield a :class:`Backend`: what the control loop needs.

The drivers need the ``hardware`` extra (python-can, python-osc, smbus2); they are imported when a
suit opens, so that ``bowden`` and its other subcommands work without it. This module is private
(leading underscore): the subcommand discovery of :mod:`bowden.cli` skips it.
"""

from __future__ import annotations

import argparse
import importlib.util
import itertools
import math
import sys
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final

from bowden.contracts import SPEED_PEAK_DEG_S
from bowden.errors import BowdenError, HardwareError, ParameterError
from bowden.hardware.ak60_codec import (
    DEFAULT_FIRMWARE,
    FIRMWARE_LIMITS,
    MAX_STANDARD_ID,
    limits_for_firmware,
)
from bowden.hardware.protocols import Clock, ElevationSensor, Motor, TensionSensor
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.runtime import MonotonicClock, SafetyConfig

if TYPE_CHECKING:
    from bowden.hardware.ads1115 import ADS1115LoadCell
    from bowden.sim.arm import PrescribedArm
    from bowden.sim.peers import WallTimePlant
    from bowden.web.reference import TrialReference

DEFAULT_IMU_PORT: Final = 8000
CAN_BITRATE: Final = 1_000_000  # the AK60-6's CAN speed (REFERENCE §4)
MAX_CALIBRATION_S: Final = 30.0

_sim_channels = itertools.count()


@dataclass
class Backend:
    """An open suit as the loop sees it, plus what the run summary reports on.

    Attributes
    ----------
    motor, imu, clock, load_cell
        The devices (the sensors stamp their samples with ``clock``).
    reference_elevation
        Reference elevation (rad) at loop time t when the suit itself follows one (the simulated
        arm), for the recording; None for the real suit.
    describe
        One line naming the devices ("AK60-6 id 1 on socketcan:can0").
    """

    motor: Motor
    imu: ElevationSensor
    clock: Clock
    load_cell: TensionSensor | None = None
    reference_elevation: Callable[[float], float] | None = None
    describe: str = ""


@dataclass(frozen=True, kw_only=True)
class CanSuitOptions:
    """Where the real suit's devices are and how to read them.

    Parameters
    ----------
    channel, interface
        python-can channel and interface of the AK60-6 (``can0``, ``socketcan``; tests: ``virtual``).
    motor_id
        The AK60-6's CAN id.
    firmware
        Key of ``ak60_codec.FIRMWARE_LIMITS`` (the MIT-mode field ranges; the sources disagree).
    direction
        +1 if positive motor torque pulls the cable, −1 if the spool is wound the other way.
    imu_port
        UDP port the NGIMU sends its OSC bundles to.
    calibration_s
        Arm-down calibration time (s) at the start of each run or trial.
    i2c_bus
        I²C bus number of the ADS1115 load cell, or None without a load cell.
    load_cell_gain_n_per_v
        Load cell and amplifier gain (N per V); the offset is tared at the start.
    """

    channel: str = "can0"
    interface: str = "socketcan"
    motor_id: int = 1
    firmware: str = DEFAULT_FIRMWARE
    direction: int = 1
    imu_port: int = DEFAULT_IMU_PORT
    calibration_s: float = 1.0
    i2c_bus: int | None = None
    load_cell_gain_n_per_v: float = 100.0

    def __post_init__(self) -> None:
        for name in ("channel", "interface"):
            if not getattr(self, name):
                raise ParameterError(f"CanSuitOptions.{name} must not be empty")
        limits_for_firmware(self.firmware)  # names the known variants if unknown
        if self.direction not in (1, -1):
            raise ParameterError(f"CanSuitOptions.direction must be +1 or -1, got {self.direction!r}")
        if not 1 <= self.imu_port <= 65535:
            raise ParameterError(f"CanSuitOptions.imu_port must be 1–65535, got {self.imu_port!r}")
        if not (math.isfinite(self.calibration_s) and 0.0 < self.calibration_s <= MAX_CALIBRATION_S):
            raise ParameterError(f"CanSuitOptions.calibration_s must be in (0, {MAX_CALIBRATION_S:g}] s, "
                                 f"got {self.calibration_s!r}")
        if self.i2c_bus is not None and self.i2c_bus < 0:
            raise ParameterError(f"CanSuitOptions.i2c_bus must be a bus number ≥ 0, got {self.i2c_bus!r}")
        gain = self.load_cell_gain_n_per_v
        if not (math.isfinite(gain) and gain != 0.0):
            raise ParameterError(
                f"CanSuitOptions.load_cell_gain_n_per_v must be finite and non-zero, got {gain!r}"
            )
        if not 1 <= self.motor_id <= MAX_STANDARD_ID:
            raise ParameterError(f"CanSuitOptions.motor_id must be a standard CAN id 1–{MAX_STANDARD_ID}, "
                                 f"got {self.motor_id!r}")

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> CanSuitOptions:
        """The options of :func:`add_can_arguments`, validated."""
        return cls(channel=args.channel, interface=args.interface, motor_id=args.motor_id,
                   firmware=args.firmware, direction=args.direction, imu_port=args.imu_port,
                   calibration_s=args.calibration_s, i2c_bus=args.i2c_bus,
                   load_cell_gain_n_per_v=args.load_cell_gain)


def add_can_arguments(parser: argparse.ArgumentParser) -> None:
    """The real suit's options (``--backend can``), one group shared by ``bowden run`` and ``serve``."""
    defaults = CanSuitOptions()
    group = parser.add_argument_group("real suit (--backend can)")
    group.add_argument("--channel", default=defaults.channel, help="CAN channel (default can0)")
    group.add_argument("--interface", default=defaults.interface,
                       help="python-can interface (default socketcan)")
    group.add_argument("--motor-id", type=int, default=defaults.motor_id, help="AK60-6 CAN id (default 1)")
    group.add_argument("--firmware", choices=sorted(FIRMWARE_LIMITS), default=defaults.firmware,
                       help="AK60-6 field ranges (the sources disagree; default: the manual's)")
    group.add_argument("--direction", type=int, choices=(1, -1), default=defaults.direction,
                       help="+1 if positive motor torque pulls the cable")
    group.add_argument("--imu-port", type=int, default=defaults.imu_port, help="NGIMU send port (8000)")
    group.add_argument("--calibration-s", type=float, default=defaults.calibration_s,
                       help="arm-down calibration time in s (default 1)")
    group.add_argument("--i2c-bus", type=int, help="I²C bus number of the ADS1115 load cell (optional)")
    group.add_argument("--load-cell-gain", type=float, default=defaults.load_cell_gain_n_per_v,
                       help="load cell N per V (default 100)")


def add_safety_arguments(parser: argparse.ArgumentParser) -> None:
    """The two watchdogs a lab may need to tune to its links (IMU over Wi-Fi, motor over CAN)."""
    imu_ms, motor_ms = 1e3 * SafetyConfig().imu_max_age_s, 1e3 * SafetyConfig().motor_max_silence_s
    group = parser.add_argument_group("watchdogs (each stops the suit safely)")
    group.add_argument("--imu-max-age-ms", type=float, default=imu_ms,
                       help=f"newest IMU sample older than this (default {imu_ms:g} ms)")
    group.add_argument("--motor-silence-ms", type=float, default=motor_ms,
                       help=f"no valid motor reply for this long (default {motor_ms:g} ms)")


def safety_config(args: argparse.Namespace) -> SafetyConfig:
    """The watchdog thresholds of :func:`add_safety_arguments`, validated."""
    return SafetyConfig(imu_max_age_s=args.imu_max_age_ms / 1e3,
                        motor_max_silence_s=args.motor_silence_ms / 1e3)


def require_hardware_extra(command: str, options: CanSuitOptions) -> None:
    """Refuse clearly, before anything starts, when a driver's library is not installed.

    Raises
    ------
    BowdenError
        Naming the missing module and the extra that provides it.
    """
    modules = ["can", "pythonosc"] + (["smbus2"] if options.i2c_bus is not None else [])
    missing = [name for name in modules if importlib.util.find_spec(name) is None]
    if missing:
        raise BowdenError(f"{command} --backend can needs the hardware extra ({', '.join(missing)} missing): "
                          "pip install 'bowden[hardware]'")


def _say(text: str) -> None:
    print(text, file=sys.stderr)


@contextmanager
def open_can_backend(options: CanSuitOptions, *, announce: Callable[[str], None] = _say) -> Iterator[Backend]:
    """The real suit: AK60-6 on ``options.channel``, NGIMU on ``options.imu_port``, optional ADS1115.

    The arm must hang still during the calibration (``options.calibration_s``); the load cell is
    tared with the cable slack. On exit the motor leaves motor mode and everything is closed.

    Raises
    ------
    HardwareError
        Naming the device that cannot be opened (no CAN interface, UDP port taken, no I²C bus), or
        an IMU that sent nothing during the calibration.
    """
    import can

    from bowden.hardware.ads1115 import ADS1115LoadCell, LoadCellCalibration
    from bowden.hardware.ak60 import AK60Config, AK60Motor
    from bowden.hardware.ngimu import NgimuClient, NgimuConfig

    config = AK60Config(motor_id=options.motor_id, limits=limits_for_firmware(options.firmware),
                        direction=options.direction)
    where = f"{options.interface}:{options.channel}"
    with ExitStack() as stack:
        try:
            bus = stack.enter_context(can.Bus(interface=options.interface, channel=options.channel,
                                              bitrate=CAN_BITRATE))
        except (can.CanError, OSError, ValueError, ImportError) as error:
            raise HardwareError(f"cannot open the CAN interface {where}: {error} "
                                "(is it up? see docs/hardware.md)") from None
        try:
            imu = stack.enter_context(NgimuClient(NgimuConfig(port=options.imu_port)))
        except OSError as error:
            raise HardwareError(f"cannot listen for the NGIMU on UDP port {options.imu_port}: "
                                f"{error.strerror or error}") from None
        announce(f"calibrating the IMU: keep the arm hanging still for {options.calibration_s:g} s")
        imu.calibrate_arm_down(options.calibration_s)
        load_cell: ADS1115LoadCell | None = None
        if options.i2c_bus is not None:
            import smbus2

            try:
                smbus = stack.enter_context(smbus2.SMBus(options.i2c_bus))
            except OSError as error:
                raise HardwareError(f"cannot open I²C bus {options.i2c_bus} for the load cell: "
                                    f"{error.strerror or error}") from None
            calibration = LoadCellCalibration(gain_n_per_v=options.load_cell_gain_n_per_v)
            load_cell = stack.enter_context(ADS1115LoadCell(smbus, calibration=calibration))
            load_cell.tare(0.5)
        motor = stack.enter_context(AK60Motor(bus, config))
        yield Backend(motor=motor, imu=imu, clock=MonotonicClock(), load_cell=load_cell,
                      describe=f"AK60-6 id {options.motor_id} on {where}")


class _ArmFollowingTheLoop:
    """A simulated participant who follows a trial's reference from the loop's first cycle on.

    The arm rests at the reference's low elevation until the loop runs, then moves as the reference
    says at loop time (rest, the repetitions, rest), as a person starts following the display. The
    instance is both the arm's motion (vectorised over plant time, for the simulator) and the
    loop's ``reference_elevation`` (plain floats): the first loop call notes the plant time of loop
    time 0, which ties the two clocks, so the recorded reference is the one the arm follows.
    """

    def __init__(self, reference: TrialReference) -> None:
        self.reference = reference
        self.plant: WallTimePlant | None = None
        self.plant_time_at_loop_start_s = math.inf  # until the loop's first cycle: rest

    def arm(self) -> PrescribedArm:
        import numpy as np

        from bowden.sim.arm import PrescribedArm

        cycle, start, end = self.reference.cycle, self.reference.start_s, self.reference.end_s

        def loop_time(plant_time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            t = plant_time_s - self.plant_time_at_loop_start_s
            return t, (t > start) & (t < end)

        def elevation(plant_time_s: np.ndarray) -> np.ndarray:
            t, moving = loop_time(plant_time_s)
            return np.where(moving, cycle.elevation_rad(np.clip(t - start, 0.0, None)), cycle.low_rad)

        def velocity(plant_time_s: np.ndarray) -> np.ndarray:
            t, moving = loop_time(plant_time_s)
            return np.where(moving, cycle.elevation_velocity_rad_s(np.clip(t - start, 0.0, None)), 0.0)

        return PrescribedArm(elevation_rad=elevation, elevation_velocity_rad_s=velocity)

    def __call__(self, time_s: float) -> float:
        if self.plant_time_at_loop_start_s == math.inf and self.plant is not None:
            self.plant_time_at_loop_start_s = self.plant.plant_time_s() - time_s
        return self.reference.elevation_rad(time_s)


@contextmanager
def open_sim_backend(
    *, speed: str = "V1", reference: TrialReference | None = None, calibration_s: float = 0.3
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
    """
    # Imported here: the real-suit path must not need the simulator's compiled kernels.
    import can

    from bowden.hardware.ads1115 import ADS1115Config, ADS1115LoadCell, LoadCellCalibration
    from bowden.hardware.ak60 import AK60Config, AK60Motor
    from bowden.hardware.ngimu import NgimuClient, NgimuConfig
    from bowden.sim.arm import PrescribedArm
    from bowden.sim.peers import ADS1115Peer, AK60Peer, FakeSMBus, NgimuPeer, WallTimePlant
    from bowden.sim.suit import SimulatedSuit

    cycle = MinimumJerkCycle(peak_speed_rad_s=math.radians(SPEED_PEAK_DEG_S[speed]))
    follower = _ArmFollowingTheLoop(reference) if reference is not None else None
    arm = follower.arm() if follower is not None else PrescribedArm.following(cycle)
    plant = WallTimePlant(SimulatedSuit(arm=arm))
    channel = f"bowden-sim-{next(_sim_channels)}"
    with ExitStack() as stack:
        driver_bus = stack.enter_context(can.Bus(interface="virtual", channel=channel))
        peer_bus = stack.enter_context(can.Bus(interface="virtual", channel=channel))
        stack.enter_context(AK60Peer(peer_bus, plant))
        imu = stack.enter_context(NgimuClient(NgimuConfig(host="127.0.0.1", port=0)))
        # 200 Hz IMU and 475 SPS ADC: realistic rates that leave the loop more of the shared CPU.
        imu_peer = stack.enter_context(NgimuPeer(plant, imu.address, rate_hz=200.0))
        smbus = stack.enter_context(FakeSMBus(ADS1115Peer(plant, offset_v=0.05, volts_per_newton=0.01)))
        calibration = LoadCellCalibration(offset_v=0.05, gain_n_per_v=100.0)
        load_cell = stack.enter_context(
            ADS1115LoadCell(smbus, ADS1115Config(data_rate=6), calibration=calibration)
        )
        imu_peer.hold_arm_down()  # the participant stands with the arm hanging for the calibration
        imu.calibrate_arm_down(calibration_s)
        imu_peer.hold_arm_down(False)
        plant.start()
        recorded: Callable[[float], float]
        if follower is not None:
            follower.plant = plant
            recorded = follower
        else:
            offset = plant.plant_time_s()

            def recorded(t: float) -> float:
                return float(cycle.elevation_rad(t + offset))

        yield Backend(
            motor=stack.enter_context(AK60Motor(driver_bus, AK60Config())),
            imu=imu, clock=MonotonicClock(), load_cell=load_cell, reference_elevation=recorded,
            describe=f"simulated suit over virtual CAN {channel}, OSC on {imu.address}, fake I²C",
        )
