"""The suit that ``bowden run`` and ``bowden serve`` drive: its command-line options and how it opens.

One place for both commands: the real suit's options (AK60-6 over CAN, NGIMU over OSC/UDP, optional
ADS1115 load cell) as a validated :class:`CanSuitOptions`, the ``argparse`` group that fills it, and
:func:`open_can_backend`, which opens the real devices and closes them safely. The simulated suit's
wiring lives beside the simulator (:func:`bowden.sim.backend.open_sim_backend`, re-exported here
and imported only when used). Both yield a :class:`~bowden.hardware.backend.Backend`.

This module is private (leading underscore): the subcommand discovery of :mod:`bowden.cli` skips it.
"""

from __future__ import annotations

import argparse
import importlib.util
import ipaddress
import math
import sys
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from bowden.cli._flag_errors import flag_errors
from bowden.errors import BowdenError, HardwareError, ParameterError
from bowden.hardware.ak60_codec import MAX_STANDARD_ID
from bowden.hardware.backend import Backend
from bowden.hardware.lsl_imu import parse_imu
from bowden.hardware.motors import AK_MOTORS, DEFAULT_MOTOR, FIRMWARE_VARIANTS, motor_model
from bowden.runtime import MonotonicClock

if TYPE_CHECKING:
    from bowden.hardware.ads1115 import ADS1115LoadCell
    from bowden.hardware.ak60 import AK60Config

__all__ = ["DEFAULT_IMU_PORT", "Backend", "CanSuitOptions", "add_can_arguments", "open_can_backend",
           "open_sim_backend", "require_hardware_extra"]

DEFAULT_IMU_PORT: Final = 8000
CAN_BITRATE: Final = 1_000_000  # the AK60-6's CAN speed (CubeMars driver manual V1.0.8 §5.3)
MAX_CALIBRATION_S: Final = 30.0


def open_sim_backend(**options: Any) -> AbstractContextManager[Backend]:
    """:func:`bowden.sim.backend.open_sim_backend` (imported here only when a simulated suit opens)."""
    from bowden.sim.backend import open_sim_backend as opener

    return opener(**options)


@dataclass(frozen=True, kw_only=True)
class CanSuitOptions:
    """Where the real suit's devices are and how to read them.

    Parameters
    ----------
    channel, interface
        python-can channel and interface of the AK60-6 (``can0``, ``socketcan``; tests: ``virtual``).
    motor_id
        The motor's CAN id.
    motor
        The AK-series model (a key of ``bowden.hardware.motors.AK_MOTORS``): its MIT-mode ranges.
    firmware
        The model's firmware variant (the MIT-mode field ranges; the sources disagree), None for the
        manual's.
    direction
        +1 if positive motor torque pulls the cable, −1 if the spool is wound the other way.
    imu
        ``ngimu`` (OSC over UDP), or ``lsl:STREAM_NAME``: any IMU streaming a quaternion (or an
        elevation) into Lab Streaming Layer (:mod:`bowden.hardware.lsl_imu`).
    imu_port
        UDP port the NGIMU sends its OSC bundles to.
    imu_host
        Address to listen on for the NGIMU: the suit's interface (``0.0.0.0``: every interface).
    imu_sender
        The NGIMU's address (``IP`` or ``IP:port``); without it, the first sender is locked in.
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
    motor: str = DEFAULT_MOTOR
    firmware: str | None = None
    direction: int = 1
    imu: str = "ngimu"
    imu_port: int = DEFAULT_IMU_PORT
    imu_host: str = "0.0.0.0"
    imu_sender: str | None = None
    calibration_s: float = 1.0
    i2c_bus: int | None = None
    load_cell_gain_n_per_v: float = 100.0

    def __post_init__(self) -> None:
        for name in ("channel", "interface"):
            if not getattr(self, name):
                raise ParameterError(f"CanSuitOptions.{name} must not be empty")
        motor_model(self.motor).limits(self.firmware)  # names the known models and variants if unknown
        parse_imu(self.imu)  # names --imu if it is neither form
        if self.direction not in (1, -1):
            raise ParameterError(f"CanSuitOptions.direction must be +1 or -1, got {self.direction!r}")
        if not 1 <= self.imu_port <= 65535:
            raise ParameterError(f"CanSuitOptions.imu_port must be 1–65535, got {self.imu_port!r}")
        try:
            ipaddress.ip_address(self.imu_host)
        except ValueError:
            raise ParameterError(f"--imu-host must be an IP address, got {self.imu_host!r}") from None
        if self.imu_sender is not None:
            from bowden.hardware.ngimu import parse_sender

            with flag_errors({"NgimuConfig.sender": "--imu-sender"}):
                parse_sender(self.imu_sender)
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
        """The options of :func:`add_can_arguments`, validated; a refusal names the flag."""
        with flag_errors(SUIT_FLAGS):
            return cls(channel=args.channel, interface=args.interface, motor_id=args.motor_id,
                       motor=args.motor, firmware=args.firmware, direction=args.direction,
                       imu=args.imu, imu_port=args.imu_port,
                       imu_host=args.imu_host, imu_sender=args.imu_sender,
                       calibration_s=args.calibration_s, i2c_bus=args.i2c_bus,
                       load_cell_gain_n_per_v=args.load_cell_gain)


# The flag of each field (all in the flag's own unit), for refusals in the commands' words.
SUIT_FLAGS: Final = {
    "CanSuitOptions.channel": "--channel",
    "CanSuitOptions.interface": "--interface",
    "CanSuitOptions.motor_id": "--motor-id",
    "CanSuitOptions.direction": "--direction",
    "CanSuitOptions.imu_port": "--imu-port",
    "CanSuitOptions.imu_host": "--imu-host",
    "CanSuitOptions.calibration_s": "--calibration-s",
    "CanSuitOptions.i2c_bus": "--i2c-bus",
    "CanSuitOptions.load_cell_gain_n_per_v": "--load-cell-gain",
}


def add_can_arguments(parser: argparse.ArgumentParser) -> None:
    """The real suit's options (``--backend can``), one group shared by ``bowden run`` and ``serve``."""
    defaults = CanSuitOptions()
    group = parser.add_argument_group("real suit (--backend can)")
    group.add_argument("--channel", default=defaults.channel, help="CAN channel (default can0)")
    group.add_argument("--interface", default=defaults.interface,
                       help="python-can interface (default socketcan)")
    group.add_argument("--motor-id", type=int, default=defaults.motor_id,
                       help="the motor's CAN id (default 1)")
    group.add_argument("--motor", choices=tuple(AK_MOTORS), default=defaults.motor,
                       help=f"the TDU's AK-series model, for its MIT-mode ranges (default {DEFAULT_MOTOR}; "
                       "also with --backend sim: the simulated motor is that model)")
    group.add_argument("--firmware", choices=FIRMWARE_VARIANTS, default=None,
                       help="the motor's firmware variant of the field ranges (the sources disagree on the "
                       "AK60-6's; default: the CubeMars manual V1.0.8's)")
    group.add_argument("--allow-other-motor", action="store_true",
                       help="use a --model identified on another --motor (its friction is another "
                       "transmission's: only for a deliberate comparison)")
    group.add_argument("--direction", type=int, choices=(1, -1), default=defaults.direction,
                       help="+1 if positive motor torque pulls the cable")
    group.add_argument("--imu", default=defaults.imu, metavar="ngimu|lsl:STREAM_NAME",
                       help="the arm's IMU: the NGIMU over OSC (default), or any IMU streaming a quaternion "
                       "(4 channels w,x,y,z) or elevation (1 channel) into Lab Streaming Layer under that "
                       "name (needs the lsl extra; also with --backend sim)")
    group.add_argument("--imu-port", type=int, default=defaults.imu_port, help="NGIMU send port (8000)")
    group.add_argument("--imu-host", default=defaults.imu_host,
                       help="address to listen on for the NGIMU (default 0.0.0.0: every interface; "
                       "give the suit's Wi-Fi address to listen there only)")
    group.add_argument("--imu-sender", help="the NGIMU's IP (or IP:port): only it is listened to "
                       "(default: the first sender, locked in and logged)")
    group.add_argument("--calibration-s", type=float, default=defaults.calibration_s,
                       help="arm-down calibration time in s (default 1)")
    group.add_argument("--i2c-bus", type=int, help="I²C bus number of the ADS1115 load cell (optional)")
    group.add_argument("--load-cell-gain", type=float, default=defaults.load_cell_gain_n_per_v,
                       help="load cell N per V (default 100)")


def require_hardware_extra(command: str, options: CanSuitOptions) -> None:
    """Refuse clearly, before anything starts, when a driver's library is not installed.

    Raises
    ------
    BowdenError
        Naming the missing module and the extra that provides it.
    """
    # python-can and python-osc are core dependencies; only the load cell's I²C library is an extra.
    modules = ["smbus2"] if options.i2c_bus is not None else []
    missing = [name for name in modules if importlib.util.find_spec(name) is None]
    if missing:
        raise BowdenError(f"{command} --backend can needs the hardware extra ({', '.join(missing)} missing): "
                          "pip install 'bowden[hardware]'")


def check_model_motor(model_path: Path | None, motor: str, *, allow_other: bool = False) -> str | None:
    """Refuse a ``model.json`` identified on another motor than ``--motor`` (unless ``allow_other``).

    Returns
    -------
    str or None
        A note for the operator when the model does not say which motor it was identified on, or
        when another motor was allowed; None when it matches (or without a model file).

    Raises
    ------
    ParameterError
        One line naming the model's motor, ``--motor`` and ``--allow-other-motor``.
    """
    if model_path is None:
        return None
    from bowden.model.model_file import recorded_motor

    recorded = recorded_motor(model_path)
    if recorded is None:
        return f"{model_path} does not record the motor it was identified on; assuming --motor {motor}"
    if recorded == motor:
        return None
    if not allow_other:
        raise ParameterError(f"--model {model_path} was identified on an {recorded}, not the "
                             f"--motor {motor}: identify on this motor, or give --allow-other-motor")
    return f"using a model identified on an {recorded} with an {motor} (--allow-other-motor)"


def _say(text: str) -> None:
    print(text, file=sys.stderr)


def motor_config(options: CanSuitOptions) -> AK60Config:
    """The driver's configuration of the TDU named by ``options`` (model, firmware, id, direction).

    The AK60-6 keeps the driver's default command clamp (its 9 Nm peak torque); another model is
    clamped at its torque field's range, the most its firmware can be asked for.
    """
    from bowden.hardware.ak60 import AK60Config

    limits = motor_model(options.motor).limits(options.firmware)
    if options.motor == DEFAULT_MOTOR:
        return AK60Config(motor_id=options.motor_id, limits=limits, direction=options.direction)
    return AK60Config(motor_id=options.motor_id, limits=limits, direction=options.direction,
                      torque_limit_nm=limits.torque_nm)


@contextmanager
def open_can_backend(options: CanSuitOptions, *, announce: Callable[[str], None] = _say,
                     mannequin: AK60Config | None = None) -> Iterator[Backend]:
    """The real suit: AK60-6 on ``options.channel``, NGIMU on ``options.imu_port``, optional ADS1115.

    The arm must hang still during the calibration (``options.calibration_s``); the load cell is
    tared with the cable slack. On exit the motor leaves motor mode and everything is closed.
    ``mannequin``: the bench's mannequin motor on the same CAN channel (``Backend.mannequin``).

    Raises
    ------
    HardwareError
        Naming the device that cannot be opened (no CAN interface, UDP port taken, no I²C bus), or
        an IMU that sent nothing during the calibration.
    """
    import can

    from bowden.hardware.ads1115 import ADS1115LoadCell, LoadCellCalibration
    from bowden.hardware.ak60 import AK60Motor
    from bowden.hardware.lsl_imu import LslImuClient, LslImuConfig
    from bowden.hardware.ngimu import NgimuClient, NgimuConfig

    config = motor_config(options)
    where = f"{options.interface}:{options.channel}"
    with ExitStack() as stack:
        try:
            bus = stack.enter_context(can.Bus(interface=options.interface, channel=options.channel,
                                              bitrate=CAN_BITRATE))
        except (can.CanError, OSError, ValueError, ImportError) as error:
            raise HardwareError(f"cannot open the CAN interface {where}: {error} "
                                "(is it up? see docs/hardware.md)") from None
        imu: NgimuClient | LslImuClient
        stream = parse_imu(options.imu)
        if stream is not None:  # resolving it names the streams that are visible if it is not
            imu = stack.enter_context(LslImuClient(LslImuConfig(stream_name=stream)))
        else:
            try:
                listen = NgimuConfig(host=options.imu_host, port=options.imu_port, sender=options.imu_sender)
                imu = stack.enter_context(NgimuClient(listen))
            except OSError as error:
                raise HardwareError(f"cannot listen for the NGIMU on {options.imu_host} UDP port "
                                    f"{options.imu_port}: {error.strerror or error}") from None
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
        second = None
        describe = f"{options.motor} id {options.motor_id} on {where}"
        if mannequin is not None:
            # Its own socket on the channel: two drivers reading one would take each other's replies.
            mannequin_bus = stack.enter_context(can.Bus(interface=options.interface, channel=options.channel,
                                                        bitrate=CAN_BITRATE))
            second = stack.enter_context(AK60Motor(mannequin_bus, mannequin))
            describe += f", mannequin motor id {mannequin.motor_id}"
        yield Backend(motor=motor, imu=imu, clock=MonotonicClock(), load_cell=load_cell,
                      describe=describe, mannequin=second)
