"""``bowden run --backend sim|can``: the controller on the suit, in a safe fixed-rate loop.

``--backend can`` drives the real suit: the AK60-6 on a socketcan channel (``--channel can0``), the
NGIMU streaming to ``--imu-port`` (the arm must hang still during the calibration at the start) and,
optionally, the load cell on an I²C bus (``--i2c-bus``). ``--backend sim`` runs the same drivers
against the simulated suit behind simulated devices that speak the same wire protocols (virtual CAN,
OSC over loopback UDP, a fake I²C bus), in real time. The run prints a status line every second and,
at the end, why it stopped and how well the loop kept time. ``--record study.db`` stores every cycle
in the study store (crash-safe). SIGINT (Ctrl-C) and SIGTERM stop the suit safely.
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bowden import __version__
from bowden.contracts import (
    CONDITION_PRETENSION,
    CONDITION_SUPPORT_25,
    CONDITION_SUPPORT_50,
    CONDITIONS,
    SPEED_PEAK_DEG_S,
    SPEEDS,
)
from bowden.control import build_controller
from bowden.errors import ParameterError
from bowden.hardware.ak60_codec import DEFAULT_FIRMWARE, FIRMWARE_LIMITS, limits_for_firmware
from bowden.hardware.protocols import Clock, ElevationSensor, Motor, TensionSensor
from bowden.model import CompensationModel, Subject
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.runtime import ControlLoop, LoopConfig, LoopReport, MonotonicClock, Recorder, Row, TrialInfo
from bowden.runtime.signals import stop_on_signals

if TYPE_CHECKING:
    from bowden.hardware.ads1115 import ADS1115LoadCell

# The drivers need the "hardware" extra (python-can, python-osc, smbus2); they are imported when a
# backend opens, so that `bowden` and its other subcommands work without it.
DEFAULT_IMU_PORT = 8000

_sim_channels = itertools.count()


@dataclass
class Backend:
    """The suit as the loop sees it, plus what the run summary reports on."""

    motor: Motor
    imu: ElevationSensor
    clock: Clock
    load_cell: TensionSensor | None = None
    reference_elevation: Callable[[float], float] | None = None
    describe: str = ""


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "run", help="run the controller on the suit (real over CAN, or simulated)",
        description=__doc__.split("\n\n")[1] if __doc__ else None,
    )
    parser.add_argument("--backend", choices=("sim", "can"), required=True)
    parser.add_argument("--model", type=Path,
                        help="model.json (required for --backend can; sim default: the ideal model)")
    parser.add_argument("--support", default="0.5",
                        help="support fraction 0-1, or 'pretension' (default 0.5)")
    parser.add_argument("--duration", type=float, default=30.0, help="run length in s (default 30)")
    parser.add_argument("--rate", type=float, default=500.0, help="control rate in Hz (default 500)")
    parser.add_argument("--record", type=Path, help="study store (SQLite) to record every cycle into")
    parser.add_argument("--participant", default="P00", help="pseudonymous participant id (default P00)")
    parser.add_argument("--condition", choices=CONDITIONS, help="condition label (default from --support)")
    parser.add_argument("--speed", choices=SPEEDS, default="V1", help="movement speed (sim arm; recorded)")
    parser.add_argument("--height", type=float, default=1.70, help="wearer stature in m (default 1.70)")
    parser.add_argument("--mass", type=float, default=63.0, help="wearer body mass in kg (default 63)")
    parser.add_argument("--sex", choices=("female", "male"), default="female")
    parser.add_argument("--hand-load", type=float, default=0.5, help="load in the hand in kg (default 0.5)")
    hardware = parser.add_argument_group("real suit (--backend can)")
    hardware.add_argument("--channel", default="can0", help="CAN channel (default can0)")
    hardware.add_argument("--interface", default="socketcan", help="python-can interface (default socketcan)")
    hardware.add_argument("--motor-id", type=int, default=1, help="AK60-6 CAN id (default 1)")
    hardware.add_argument("--firmware", choices=sorted(FIRMWARE_LIMITS), default=DEFAULT_FIRMWARE,
                          help="AK60-6 field ranges (the sources disagree; default: the manual's)")
    hardware.add_argument("--direction", type=int, choices=(1, -1), default=1,
                          help="+1 if positive motor torque pulls the cable")
    hardware.add_argument("--imu-port", type=int, default=DEFAULT_IMU_PORT, help="NGIMU send port (8000)")
    hardware.add_argument("--calibration-s", type=float, default=1.0, help="arm-down calibration time in s")
    hardware.add_argument("--i2c-bus", type=int, help="I²C bus number of the ADS1115 load cell (optional)")
    hardware.add_argument("--load-cell-gain", type=float, default=100.0, help="load cell N per V")
    parser.set_defaults(handler=run)


def _support(text: str) -> float | str:
    if text == "pretension":
        return "pretension"
    try:
        value = float(text)
    except ValueError:
        raise ParameterError(f"--support must be a fraction 0-1 or 'pretension', got {text!r}") from None
    if not 0.0 <= value <= 1.0:
        raise ParameterError(f"--support must be within 0-1, got {value}")
    return value


def _condition(support: float | str, given: str | None) -> str:
    if given is not None:
        return given
    named = {"pretension": CONDITION_PRETENSION, 0.25: CONDITION_SUPPORT_25, 0.5: CONDITION_SUPPORT_50}
    if support in named:
        return named[support]
    raise ParameterError(f"no study condition for support {support}: give --condition")


@contextmanager
def open_sim_backend(*, speed: str = "V1", calibration_s: float = 0.3) -> Iterator[Backend]:
    """The simulated suit behind its wire peers, driven by the real drivers (all closed on exit)."""
    # Imported here: the real-suit path must not need the simulator's compiled kernels.
    import can

    from bowden.hardware.ads1115 import ADS1115Config, ADS1115LoadCell, LoadCellCalibration
    from bowden.hardware.ak60 import AK60Config, AK60Motor
    from bowden.hardware.ngimu import NgimuClient, NgimuConfig
    from bowden.sim.arm import PrescribedArm
    from bowden.sim.peers import ADS1115Peer, AK60Peer, FakeSMBus, NgimuPeer, WallTimePlant
    from bowden.sim.suit import SimulatedSuit

    cycle = MinimumJerkCycle(peak_speed_rad_s=math.radians(SPEED_PEAK_DEG_S[speed]))
    plant = WallTimePlant(SimulatedSuit(arm=PrescribedArm.following(cycle)))
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
        offset = plant.plant_time_s()
        yield Backend(
            motor=stack.enter_context(AK60Motor(driver_bus, AK60Config())),
            imu=imu, clock=MonotonicClock(), load_cell=load_cell,
            reference_elevation=lambda t: float(cycle.elevation_rad(t + offset)),
            describe=f"simulated suit over virtual CAN {channel}, OSC on {imu.address}, fake I²C",
        )


@contextmanager
def open_can_backend(args: argparse.Namespace) -> Iterator[Backend]:
    """The real suit: AK60-6 on ``args.channel``, NGIMU on ``args.imu_port``, optional ADS1115."""
    import can

    from bowden.hardware.ads1115 import ADS1115LoadCell, LoadCellCalibration
    from bowden.hardware.ak60 import AK60Config, AK60Motor
    from bowden.hardware.ngimu import NgimuClient, NgimuConfig

    config = AK60Config(motor_id=args.motor_id, limits=limits_for_firmware(args.firmware),
                        direction=args.direction)
    with ExitStack() as stack:
        bus = stack.enter_context(can.Bus(interface=args.interface, channel=args.channel, bitrate=1_000_000))
        imu = stack.enter_context(NgimuClient(NgimuConfig(port=args.imu_port)))
        print(f"calibrating the IMU: keep the arm hanging still for {args.calibration_s:g} s",
              file=sys.stderr)
        imu.calibrate_arm_down(args.calibration_s)
        load_cell: ADS1115LoadCell | None = None
        if args.i2c_bus is not None:
            import smbus2

            smbus = stack.enter_context(smbus2.SMBus(args.i2c_bus))
            load_cell = stack.enter_context(
                ADS1115LoadCell(smbus, calibration=LoadCellCalibration(gain_n_per_v=args.load_cell_gain))
            )
            load_cell.tare(0.5)
        motor = stack.enter_context(AK60Motor(bus, config))
        yield Backend(motor=motor, imu=imu, clock=MonotonicClock(), load_cell=load_cell,
                      describe=f"AK60-6 id {args.motor_id} on {args.interface}:{args.channel}")


class _Status:
    """Keeps the latest row and prints a status line once per second from its own thread."""

    def __init__(self, forward: Callable[[Row], None] | None) -> None:
        self.forward = forward
        self.latest: Row | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._print, name="status", daemon=True)

    def __call__(self, row: Row) -> None:
        self.latest = row
        if self.forward is not None:
            self.forward(row)

    def _print(self) -> None:
        while not self._stop.wait(1.0):
            row = self.latest
            if row is not None:
                print(f"t {row[0]:6.1f} s  elevation {math.degrees(row[2]):6.1f}°  desired {row[4]:5.1f} N  "
                      f"torque {row[6]:5.2f} Nm  load cell {row[9]:6.1f} N", file=sys.stderr)

    def __enter__(self) -> _Status:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


def run_trial(args: argparse.Namespace, backend: Backend, recorder: Recorder | None) -> LoopReport:
    """Build the controller and run one trial on ``backend`` (SIGINT/SIGTERM stop it safely)."""
    support = _support(args.support)
    if args.model is not None:
        model = CompensationModel.load(args.model)
    else:
        from bowden.sim.parameters import SuitParameters

        model = CompensationModel.from_friction(k=SuitParameters().sheath.kinetic_coefficient)
    controller = build_controller(
        model=model, support=support,  # type: ignore[arg-type]  # "pretension" checked by _support
        subject=Subject(height_m=args.height, mass_kg=args.mass, sex=args.sex), hand_load_kg=args.hand_load,
    )
    loop = ControlLoop(
        controller=controller, motor=backend.motor, elevation_sensor=backend.imu, clock=backend.clock,
        config=LoopConfig(rate_hz=args.rate, duration_s=args.duration), tension_sensor=backend.load_cell,
        reference_elevation=backend.reference_elevation,
    )
    forward = recorder.record if recorder is not None else None
    with _Status(forward) as status, stop_on_signals(loop.request_stop):
        loop.record = status
        return loop.run()


def run(args: argparse.Namespace) -> int:
    support = _support(args.support)
    if args.backend == "can" and args.model is None:
        raise ParameterError("--backend can needs --model model.json (run `bowden identify` first)")
    # Everything that can be wrong with the arguments is found before any device is touched.
    LoopConfig(rate_hz=args.rate, duration_s=args.duration)
    trial = None
    if args.record is not None:
        metadata: dict[str, Any] = {"backend": args.backend, "rate_hz": args.rate, "bowden": __version__,
                                    "model": str(args.model) if args.model else "ideal (simulation)"}
        trial = TrialInfo(participant=args.participant, condition=_condition(support, args.condition),
                          speed=args.speed, support=support if isinstance(support, float) else None,
                          metadata=metadata)
    opener = open_sim_backend(speed=args.speed) if args.backend == "sim" else open_can_backend(args)
    with opener as backend:
        print(f"bowden run: {backend.describe}", file=sys.stderr)
        recorder = Recorder(args.record, trial).start() if trial is not None else None
        stop_reason = "error: the run did not finish"
        try:
            report = run_trial(args, backend, recorder)
            stop_reason = report.reason
            if recorder is not None:
                fault = report.fault.name if report.fault else "NONE"
                recorder.event(report.stop_time_s, "safe_stop", f"{fault}: {report.reason}")
        finally:
            if recorder is not None:
                recorder.close(stop_reason=stop_reason)
    print(f"stopped: {report.reason} ({report.fault.name if report.fault else 'no fault'})")
    ramp_ms = 1e3 * (report.zero_torque_time_s - report.stop_time_s)
    exited = "exited" if report.motor_disabled else "NOT confirmed exited"
    print(f"safe state: torque zero {ramp_ms:.0f} ms after the stop, motor mode {exited}")
    print(f"loop timing: {report.timing.describe()}; motor timeouts {report.motor_timeouts}")
    if recorder is not None:
        gap_ms = 1e3 * recorder.stats.max_commit_gap_s
        print(f"recorded {recorder.stats.committed_rows} cycles into {args.record} "
              f"(trial {recorder.trial_id}, longest gap between commits {gap_ms:.0f} ms)")
    return 0 if report.clean else 3
