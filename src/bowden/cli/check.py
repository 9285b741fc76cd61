"""``bowden check``: the pre-flight, before the participant arrives.

One line per check — the CAN interface up at 1 Mbit/s; the motor found on its id, answering, its
temperature and error code; the IMU streaming at the expected rate from the expected sender, its
elevation plausible with the arm hanging; the load cell reading zero with the cable slack; the trigger
line toggling; the LSL outlets visible; the store writable with room for the session; the model
file's motor matching ``--motor`` — each ok, or what is wrong and what to do. The exit code is 1 when
any check fails; ``--json`` prints the same checks for the console. ``--backend sim`` checks the
simulated suit (``--inject FAULT`` breaks it first, for tests and demonstrations). The motor enters
motor mode for one reply and leaves it; no torque is commanded.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bowden.cli._suit import CanSuitOptions, add_can_arguments, check_model_motor, motor_config
from bowden.errors import BowdenError, ParameterError
from bowden.hardware.lsl_imu import parse_imu
from bowden.hardware.motors import motor_model
from bowden.hardware.preflight import (
    CAN_BITRATE,
    Check,
    LinkState,
    check_can_link,
    check_imu_stream,
    check_load_cell,
    check_motor,
    check_store,
    socketcan_link,
)

if TYPE_CHECKING:
    from bowden.sim.peers.check_rig import SimulatedRig

MAX_SESSION_MIN = 24 * 60.0
INJECTABLE = "interface-down, silent-imu, load-cell-offset, hot-motor"  # bowden.sim.peers.check_rig.FAULTS


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "check", help="pre-flight: check every device of the suit before the participant arrives",
        description=__doc__.split("\n\n")[1] if __doc__ else None,
    )
    parser.add_argument("--backend", choices=("sim", "can"), required=True)
    parser.add_argument("--json", action="store_true", help="print the checks as JSON (for the console)")
    parser.add_argument("--imu-rate", type=float, default=200.0,
                        help="orientations per second the IMU should send (default 200)")
    parser.add_argument("--model", type=Path,
                        help="model.json of the session: loads, and its motor is --motor")
    parser.add_argument("--record", type=Path, help="the session's study store: writable, with room")
    parser.add_argument("--session-min", type=float, default=60.0,
                        help="session length to find room for, in min (default 60)")
    parser.add_argument("--rate", type=float, default=500.0,
                        help="control rate of the runs, Hz (default 500)")
    parser.add_argument("--trigger", metavar="SPEC", help="the trigger line to toggle (as bowden run's)")
    parser.add_argument("--lsl", action="store_true", help="publish the LSL outlets and find them")
    # No choices= here: the simulated rig (which imports python-can) names the known faults itself,
    # and building the command line must not import it.
    parser.add_argument("--inject", action="append", default=[], metavar="FAULT",
                        help=f"--backend sim: break the simulated suit first (repeatable): {INJECTABLE}")
    add_can_arguments(parser)
    parser.set_defaults(handler=check)


def check(args: argparse.Namespace) -> int:
    options = CanSuitOptions.from_args(args)
    _validate(args)
    # The drivers log what they retry; here each check's line says what came of it.
    drivers = logging.getLogger("bowden.hardware")
    level = drivers.level
    drivers.setLevel(logging.ERROR)
    try:
        checks = run_checks(args, options)
    finally:
        drivers.setLevel(level)
    if args.json:
        print(json.dumps({"ok": all(c.ok for c in checks), "checks": [c.to_json() for c in checks]}))
    else:
        for item in checks:
            print(item.line())
    return 0 if all(c.ok for c in checks) else 1


def preflight_report(served: argparse.Namespace) -> dict[str, object]:
    """``bowden check --json``'s report for the suit ``bowden serve`` was started with (its console's
    pre-flight): the same suit options, its model and its store. The trigger line and the LSL outlets
    are left out: the server holds them open already (opening them was their check)."""
    args = argparse.Namespace(**vars(served))
    args.imu_rate, args.session_min, args.inject, args.lsl, args.trigger = 200.0, 60.0, [], False, None
    args.record, args.rate = served.store, served.rate_hz
    checks = run_checks(args, CanSuitOptions.from_args(args))
    return {"ok": all(c.ok for c in checks), "checks": [c.to_json() for c in checks]}


def _validate(args: argparse.Namespace) -> None:
    if not (math.isfinite(args.imu_rate) and 1.0 <= args.imu_rate <= 2000.0):
        raise ParameterError(f"--imu-rate must be 1–2000 Hz, got {args.imu_rate:g}")
    if not (math.isfinite(args.session_min) and 0.0 < args.session_min <= MAX_SESSION_MIN):
        raise ParameterError(f"--session-min must be in (0, {MAX_SESSION_MIN:g}] min, "
                             f"got {args.session_min:g}")
    if not (math.isfinite(args.rate) and 1.0 <= args.rate <= 2000.0):
        raise ParameterError(f"--rate must be 1–2000 Hz, got {args.rate:g}")
    if args.inject and args.backend != "sim":
        raise ParameterError("--inject breaks the simulated suit only: give --backend sim")


def run_checks(args: argparse.Namespace, options: CanSuitOptions) -> list[Check]:
    """Every check the arguments ask for, each device opened on its own."""
    checks: list[Check] = []
    with ExitStack() as stack:
        rig = None
        if args.backend == "sim":
            from bowden.sim.peers.check_rig import simulated_rig

            limits = motor_model(options.motor).limits(options.firmware)
            rig = stack.enter_context(simulated_rig(limits, frozenset(args.inject)))
        checks.append(_can(options, rig))
        checks.append(_motor(options, rig) if checks[-1].ok else
                      Check("motor", False, "not checked: the CAN interface is not usable"))
        checks.append(_imu(args, options, rig))
        if rig is not None or options.i2c_bus is not None:
            checks.append(_load_cell(options, rig))
    if args.trigger is not None:
        checks.append(_trigger(args.trigger))
    if args.lsl:
        checks.append(_lsl(args.rate))
    if args.record is not None:
        checks.append(_store(args.record, session_s=60.0 * args.session_min, rate_hz=args.rate))
    if args.model is not None:
        checks.append(_model(args.model, options.motor, allow_other=args.allow_other_motor))
    return checks


def _can(options: CanSuitOptions, rig: SimulatedRig | None) -> Check:
    if rig is not None:
        state = LinkState(exists=True, up=rig.link_up, bitrate=CAN_BITRATE)
        return check_can_link(options.channel, state)  # named as the real interface would be
    if options.interface != "socketcan":
        return Check("can", True, f"{options.interface}:{options.channel} (no link state for this interface)")
    return check_can_link(options.channel, socketcan_link(options.channel))


def _motor(options: CanSuitOptions, rig: SimulatedRig | None) -> Check:
    import can

    from bowden.hardware.ak60 import AK60Motor

    interface, channel = options.interface, options.channel
    if rig is not None:
        interface, channel = "virtual", rig.can_channel
    try:
        bus = can.Bus(interface=interface, channel=channel, bitrate=CAN_BITRATE)
    except (can.CanError, OSError, ValueError, ImportError) as error:
        return Check("motor", False, f"cannot open the CAN interface {interface}:{channel}: {error}")
    try:
        motor = AK60Motor(bus, motor_config(options))
        return check_motor(motor, motor_model(options.motor), options.firmware)
    finally:
        bus.shutdown()


def _imu(args: argparse.Namespace, options: CanSuitOptions, rig: SimulatedRig | None) -> Check:
    stream = parse_imu(options.imu)
    if stream is not None:
        return _lsl_imu(args, stream, options.calibration_s, rig)
    from bowden.hardware.ngimu import NgimuClient, NgimuConfig

    host, port = ("127.0.0.1", 0) if rig is not None else (options.imu_host, options.imu_port)
    try:
        client = NgimuClient(NgimuConfig(host=host, port=port, sender=options.imu_sender)).start()
    except OSError as error:
        return Check("imu", False, f"cannot listen on {host} UDP port {port}: {error.strerror or error} "
                     "(another program on --imu-port?)")
    with client:
        if rig is not None:
            rig.start_imu(client.address, rate_hz=200.0)
        try:
            client.calibrate_arm_down(options.calibration_s)
        except BowdenError:
            return _silent_imu(client, options)
        return check_imu_stream(client, lambda: client.counters.quaternions, expected_rate_hz=args.imu_rate)


def _lsl_imu(args: argparse.Namespace, stream: str, calibration_s: float, rig: SimulatedRig | None) -> Check:
    from bowden.hardware.lsl_imu import LslImuClient, LslImuConfig

    if rig is not None:
        rig.start_imu(stream, rate_hz=200.0)  # the stream exists before the client looks for it
    try:
        client = LslImuClient(LslImuConfig(stream_name=stream)).start()
    except BowdenError as error:
        return Check("imu", False, str(error))
    with client:
        try:
            client.calibrate_arm_down(calibration_s)
        except BowdenError as error:
            return Check("imu", False, str(error))
        return check_imu_stream(client, lambda: client.counters.samples - client.counters.stale,
                                expected_rate_hz=args.imu_rate)


def _silent_imu(client: Any, options: CanSuitOptions) -> Check:
    port = client.address[1]
    if client.counters.foreign:
        return Check("imu", False, f"nothing from --imu-sender {options.imu_sender}, but "
                     f"{client.counters.foreign} datagrams from another source: is --imu-sender the IMU's "
                     "address?")
    return Check("imu", False, f"no orientation in {options.calibration_s:g} s on UDP port {port}: is the "
                 "IMU on, on this network, and sending /quaternion to this host's --imu-port?")


def _load_cell(options: CanSuitOptions, rig: SimulatedRig | None) -> Check:
    from bowden.hardware.ads1115 import ADS1115Config, ADS1115LoadCell, LoadCellCalibration

    with ExitStack() as stack:
        if rig is not None:
            from bowden.sim.peers.check_rig import LOAD_CELL_OFFSET_V

            smbus: Any = rig.smbus
            calibration = LoadCellCalibration(offset_v=LOAD_CELL_OFFSET_V,
                                              gain_n_per_v=options.load_cell_gain_n_per_v)
        else:
            import smbus2

            try:
                smbus = stack.enter_context(smbus2.SMBus(options.i2c_bus))
            except OSError as error:
                return Check("load_cell", False, f"cannot open I²C bus {options.i2c_bus} (--i2c-bus): "
                             f"{error.strerror or error}")
            calibration = LoadCellCalibration(gain_n_per_v=options.load_cell_gain_n_per_v)
        try:
            load_cell = stack.enter_context(ADS1115LoadCell(smbus, ADS1115Config(data_rate=6),
                                                            calibration=calibration))
        except (OSError, BowdenError) as error:
            return Check("load_cell", False, f"the ADS1115 does not answer: {error} (i2cdetect; --i2c-bus)")
        return check_load_cell(load_cell)


def _trigger(spec: str) -> Check:
    from bowden.hardware.trigger import open_trigger

    try:
        line = open_trigger(spec)
    except BowdenError as error:
        return Check("trigger", False, f"cannot open --trigger {spec}: {error}")
    try:
        high = line.set(True)
        low = line.set(False)
    except (BowdenError, OSError) as error:
        return Check("trigger", False, f"--trigger {spec} did not toggle: {error}")
    finally:
        line.close()
    took_ms = max(high[1] - high[0], low[1] - low[0]) * 1000.0
    return Check("trigger", True, f"toggled high and low (each edge sent within {took_ms:.2f} ms)")


def _lsl(rate_hz: float) -> Check:
    from bowden.runtime.lsl_outlets import LslOutlets

    try:
        outlets = LslOutlets(rate_hz=rate_hz)
    except BowdenError as error:
        return Check("lsl", False, str(error))
    try:
        import pylsl

        found = {info.source_id() for info in pylsl.resolve_streams(wait_time=1.0)}
        wanted = (outlets.marker_source_id, outlets.loop_source_id)
        missing = [name for name in wanted if name not in found]
    finally:
        outlets.close(linger_s=0.0)
    if missing:
        return Check("lsl", False, f"published {', '.join(missing)} but cannot find it: is multicast "
                     "blocked, or liblsl's ResolveScope too narrow (lsl_api.cfg)?")
    return Check("lsl", True, f"{' and '.join(wanted)} visible")


def _store(path: Path, *, session_s: float, rate_hz: float) -> Check:
    """``--record``: an existing file must be a bowden store (``bowden run`` would refuse it at the
    trial); then its folder must take files, with room for the session."""
    if path.is_dir():
        return Check("store", False, f"--record {path} is a directory: give the store's file (study.db)")
    if path.exists():
        problem = _not_a_store(path)
        if problem is not None:
            return Check("store", False, f"--record {problem}")
    return check_store(path, session_s=session_s, rate_hz=rate_hz)


def _not_a_store(path: Path) -> str | None:
    """Why the existing file ``path`` is not a bowden store (None if it is one), read-only."""
    import sqlite3

    from bowden.errors import StoreError
    from bowden.store.schema import check_store as check_store_file

    try:
        connection = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
    except sqlite3.Error as error:
        return f"{path}: cannot be opened ({error})"
    try:
        check_store_file(connection)
    except StoreError as error:
        return str(error)
    finally:
        connection.close()
    return None


def _model(path: Path, motor: str, *, allow_other: bool) -> Check:
    from bowden.model.model_file import load_model

    try:
        load_model(path)
        note = check_model_motor(path, motor, allow_other=allow_other)
    except BowdenError as error:
        return Check("model", False, str(error))
    return Check("model", True, f"{path} loads, identified on the {motor}" if note is None
                 else f"{path} loads; {note}")
