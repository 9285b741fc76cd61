"""``bowden run --backend sim|can``: the controller on the suit, in a safe fixed-rate loop.

``--backend can`` drives the real suit: the AK60-6 on a socketcan channel (``--channel can0``), the
NGIMU streaming to ``--imu-port`` (the arm must hang still during the calibration at the start) and,
optionally, the load cell on an I²C bus (``--i2c-bus``). ``--backend sim`` runs the same drivers
against the simulated suit in a process of its own, behind simulated devices that speak the same wire
protocols (CAN across processes, OSC over loopback UDP, I²C over a local socket), in real time. The
run prints a status line every second and, at the end, why it stopped, how well the loop kept time
and what the host and the devices did (stalls, missing replies, degraded states). ``--record
study.db`` stores every cycle in the study store (crash-safe), with the wearer's anthropometrics
(participants table and trial metadata). Every argument, the wearer and the store are checked before
any device is opened. SIGINT (Ctrl-C) and SIGTERM stop the suit safely. ``--serve`` also serves the
participant display, the operator console (live plots, loop health, a stop button that puts the suit
in its safe state) and the questionnaires while the run lasts.
"""

from __future__ import annotations

import argparse
import math
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from bowden.cli._flag_errors import flag_errors
from bowden.cli._loop_options import add_safety_arguments, realtime_config, safety_config, slack_config
from bowden.cli._outputs import check_output_file
from bowden.cli._protocol_options import add_protocol_arguments, protocol_catalogue
from bowden.cli._run_plan import (
    controller_for,
    fill_wearer,
    record_participant,
    run_model,
    run_reference,
    support_and_condition,
    trial_info,
    trial_setup_of,
    wearer,
)
from bowden.cli._suit import (
    DEFAULT_IMU_PORT,
    Backend,
    CanSuitOptions,
    add_can_arguments,
    check_model_motor,
    open_can_backend,
    open_sim_backend,
    require_hardware_extra,
)
from bowden.cli._sync_options import add_sync_arguments, open_sync_outputs
from bowden.cli._sync_options import trigger_report as _trigger_report
from bowden.contracts import CONDITIONS, SPEEDS
from bowden.errors import BowdenError, ParameterError, StoreError
from bowden.hardware.lsl_imu import parse_imu
from bowden.model import CompensationModel
from bowden.protocol.catalogue import Catalogue
from bowden.runtime import ControlLoop, LoopConfig, LoopReport, Row
from bowden.runtime.loop import StepController
from bowden.runtime.signals import stop_on_signals
from bowden.runtime.slack import SlackTakeUp
from bowden.runtime.trial_sync import TrialSync
from bowden.web.reference import TrialReference
from bowden.web.trial_setup import TrialSetup
from bowden.web.validation import participant_id

if TYPE_CHECKING:
    from bowden.runtime.recorder import Recorder, TrialInfo
    from bowden.web.server import ServerThread

__all__ = ["DEFAULT_IMU_PORT", "Backend", "open_can_backend", "open_sim_backend", "register", "run"]

# Where --serve listens unless --host/--port say otherwise (this machine only; bowden serve's port).
SERVE_HOST = "127.0.0.1"
SERVE_PORT = 8765
DRAIN_S = 2.0  # at the end, how long the browsers get to receive the last messages


def _say(text: str) -> None:
    print(f"bowden run: {text}", file=sys.stderr, flush=True)


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "run",
        help="run the controller on the suit (real over CAN, or simulated)",
        description=__doc__.split("\n\n")[1] if __doc__ else None,
    )
    parser.add_argument("--backend", choices=("sim", "can"), required=True)
    parser.add_argument(
        "--model", type=Path, help="model.json (required for --backend can; sim default: the ideal model)"
    )
    parser.add_argument(
        "--support", help="support fraction 0-1, or 'pretension' (default: the --condition's, else 0.5)"
    )
    parser.add_argument("--duration", type=float, default=30.0, help="run length in s (default 30)")
    parser.add_argument("--rate", type=float, default=500.0, help="control rate in Hz (default 500)")
    parser.add_argument(
        "--compensation", choices=("paper", "dynamic"),
        help="friction compensation (default: the model's recommendation, dynamic in a version-2 model)",
    )
    parser.add_argument("--record", type=Path, help="study store (SQLite) to record every cycle into")
    parser.add_argument(
        "--participant", default="P00",
        help="pseudonymous participant id (default P00); with --record, a participant registered in the "
        "store (bowden serve's console) runs with the registered height, mass, sex and hand load",
    )
    parser.add_argument(
        "--condition",
        help=f"study condition: {', '.join(CONDITIONS)} or one of --define-condition (default from "
        "--support; must agree with it: no_suit runs the motor at zero torque)",
    )
    parser.add_argument(
        "--speed",
        default="V1",
        help=f"speed of the reference: {', '.join(SPEEDS)} or one of --define-speed (default V1; the "
        "sim arm follows it; recorded)",
    )
    add_protocol_arguments(parser)
    parser.add_argument(
        "--lead-in", type=float, default=2.0, help="rest before the reference starts moving, s (default 2)"
    )
    parser.add_argument("--height", type=float,
                        help="wearer stature in m (default: the registry's, else 1.70)")
    parser.add_argument("--mass", type=float,
                        help="wearer body mass in kg (default: the registry's, else 63)")
    parser.add_argument("--sex", choices=("female", "male"), help="(default: the registry's, else female)")
    parser.add_argument("--hand-load", type=float,
                        help="load in the hand in kg (default: the registry's, else 0.5)")
    web = parser.add_argument_group("browser (--serve, needs the web extra)")
    web.add_argument(
        "--serve",
        action="store_true",
        help="also serve the participant display, operator console and questionnaires "
        "while the run lasts (needs --record)",
    )
    web.add_argument(
        "--host",
        help=f"with --serve: address to listen on (default {SERVE_HOST}: this machine only)",
    )
    web.add_argument(
        "--port", type=int, help=f"with --serve: port (default {SERVE_PORT}; 0 picks a free one)"
    )
    add_sync_arguments(parser, trials="the trial")
    add_safety_arguments(parser)
    add_can_arguments(parser)
    parser.set_defaults(handler=run)


class _Status:
    """Hands each row to its sinks, keeps the latest, and prints a status line once per second."""

    def __init__(self, sinks: list[Callable[[Row], None]]) -> None:
        self.sinks = sinks
        self.latest: Row | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._print, name="status", daemon=True)

    def __call__(self, row: Row) -> None:
        self.latest = row
        for sink in self.sinks:
            sink(row)

    def _print(self) -> None:
        while not self._stop.wait(1.0):
            row = self.latest
            if row is not None:
                print(
                    f"t {row[0]:6.1f} s  elevation {math.degrees(row[2]):6.1f}°  desired {row[4]:5.1f} N  "
                    f"torque {row[6]:5.2f} Nm  load cell {row[9]:6.1f} N",
                    file=sys.stderr,
                )

    def __enter__(self) -> _Status:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


@contextmanager
def _serving(args: argparse.Namespace, model: CompensationModel) -> Iterator[ServerThread]:
    """The web server in its own thread (own event loop) for as long as the run lasts."""
    try:
        from bowden.web.server import ServeConfig, ServerThread
        from bowden.web.suits import CommandLineBackend
    except ImportError as error:
        raise BowdenError(
            f"bowden run --serve needs the web extra ({error.name} is missing): pip install 'bowden[web]'"
        ) from None
    with flag_errors({"ServeConfig.port": "--port", "ServeConfig.host": "--host"}):
        config = ServeConfig(
            store_path=args.record,
            model=model,
            backend=CommandLineBackend(args.backend),
            host=SERVE_HOST if args.host is None else args.host,
            port=SERVE_PORT if args.port is None else args.port,
            rate_hz=args.rate,
            safety=safety_config(args),
        )
    with ServerThread(config) as server:
        for line in server.announcement(title="bowden run --serve"):
            print(line, flush=True)
        try:
            yield server
        finally:
            # Let the browsers receive the end of the trial before the server goes.
            deadline = time.monotonic() + DRAIN_S
            while server.web.manager.hub.pending() and time.monotonic() < deadline:
                time.sleep(0.02)


def run_trial(
    args: argparse.Namespace,
    backend: Backend,
    recorder: Recorder | None,
    *,
    controller: StepController,
    reference: TrialReference,
    setup: TrialSetup | None = None,
    server: ServerThread | None = None,
    slack: SlackTakeUp | None = None,
    sync: TrialSync | None = None,
) -> LoopReport:
    """Run one trial of ``controller`` on ``backend`` (SIGINT/SIGTERM stop it safely).

    With ``server`` (and the trial's ``setup``), the trial is also the server's current trial: its
    rows go to the browsers through a non-blocking tap, and the console's stop button asks this
    loop for its safe stop.
    """
    # The real suit follows no reference of its own; one is recorded when it is shown (--serve).
    shown = reference.elevation_rad if server is not None else None
    loop = ControlLoop(
        controller=controller,
        motor=backend.motor,
        elevation_sensor=backend.imu,
        clock=backend.clock,
        config=LoopConfig(rate_hz=args.rate, duration_s=args.duration, safety=safety_config(args),
                          slack=slack),
        tension_sensor=backend.load_cell,
        reference_elevation=backend.reference_elevation or shown,
    )
    sinks: list[Callable[[Row], None]] = [recorder.record] if recorder is not None else []
    if server is not None and recorder is not None and setup is not None:
        from bowden.web.suits import OpenSuit

        suit = OpenSuit(
            motor=backend.motor,
            elevation_sensor=backend.imu,
            clock=backend.clock,
            tension_sensor=backend.load_cell,
            description=backend.describe,
        )
        sinks.append(server.web.manager.attach(setup, suit, loop, recorder))
    if recorder is not None:
        loop.recorder_failure = lambda: recorder.failure
        loop.on_event = recorder.event
    if sync is not None:
        sinks.append(sync.row)
    loop.realtime = realtime_config(args)
    with _Status(sinks) as status, stop_on_signals(loop.request_stop):
        loop.record = status
        report = loop.run()
    if sync is not None:
        sync.finish(stop_time_s=report.stop_time_s, reason=report.reason, clean=report.clean)
    return report


def _trial_sync(
    args: argparse.Namespace,
    stack: ExitStack,
    recorder: Recorder | None,
    reference: TrialReference,
    participant: str,
    condition: str | None,
) -> TrialSync | None:
    """The trial's trigger line and LSL outlets (``--trigger``, ``--lsl``); None when neither is asked."""
    outputs = open_sync_outputs(args, stack, rate_hz=args.rate, say=_say)
    if outputs is None:
        return None
    session = {
        "participant": participant,
        "condition": condition,
        "speed": args.speed,
        "store": args.record.name if args.record is not None else None,
    }
    return outputs.trial(
        trial_id=recorder.trial_id if recorder is not None else None,
        on_event=recorder.event if recorder is not None else None,
        reference=reference,
        session=session,
    )


@dataclass
class _Prepared:
    """Everything a run needs, checked before any device is touched."""

    suit: CanSuitOptions
    real_suit: CanSuitOptions | None  # None: the simulated suit
    participant: str
    condition: str | None
    reference: TrialReference
    model: CompensationModel
    slack: SlackTakeUp | None
    controller: StepController
    setup: TrialSetup | None
    trial: TrialInfo | None


@dataclass
class _Outcome:
    report: LoopReport
    backend: Backend | None
    recorder: Recorder | None
    sync: TrialSync | None
    recording_error: str


def run(args: argparse.Namespace) -> int:
    prepared = _prepare(args)
    outcome = _execute(args, prepared)
    _summarise(args, prepared, outcome)
    return 0 if outcome.report.clean else 3


def _prepare(args: argparse.Namespace) -> _Prepared:
    """Find everything that can be wrong before any device is touched (on the real suit, opening it
    enters motor mode): the limits, the reference, the model, the wearer, the controller, and the
    store, which must open and take the participant."""
    # The conditions and speeds: the paper's, --define-condition/--define-speed and the store's own.
    catalogue: Catalogue = protocol_catalogue(
        args, args.record if args.record is not None and args.record.is_file() else None
    )
    support, condition = support_and_condition(args.support, args.condition, catalogue)
    participant = participant_id(args.participant, "--participant")
    suit = CanSuitOptions.from_args(args)  # the motor's model and firmware count on either backend
    real_suit = None
    if args.backend == "can":
        if args.model is None:
            raise ParameterError("--backend can needs --model model.json (run `bowden identify` first)")
        real_suit = suit
        require_hardware_extra("bowden run", real_suit)
    if args.serve and args.record is None:
        raise ParameterError("--serve needs --record study.db (the trial and the questionnaires go there)")
    if not args.serve and (args.host is not None or args.port is not None):
        raise ParameterError("--host and --port say where --serve listens: add --serve, or leave them out")
    if args.record is not None:  # said now, in the flag's words (SQLite says "unable to open database file")
        check_output_file("the study store (--record)", args.record, create_parents=True)
    if args.record is not None and condition is None:
        raise ParameterError(f"no study condition for support {support}: give --condition")
    if not (math.isfinite(args.rate) and 1.0 <= args.rate <= 2000.0):
        raise ParameterError(f"--rate must be 1–2000 Hz, got {args.rate:g}")
    if not (math.isfinite(args.duration) and args.duration > 0.0):
        raise ParameterError(f"--duration must be a positive number of seconds, got {args.duration:g}")
    LoopConfig(rate_hz=args.rate, duration_s=args.duration, safety=safety_config(args))
    realtime_config(args)
    reference = run_reference(args, catalogue)
    model = run_model(args)
    motor_note = check_model_motor(args.model, suit.motor, allow_other=args.allow_other_motor)
    if motor_note is not None:
        _say(motor_note)
    slack = slack_config(args, model.pulley_radius_m)
    fill_wearer(args, participant)
    subject = wearer(args)
    controller = controller_for(
        model, support, subject, args.hand_load, compensation=args.compensation, rate_hz=args.rate,
        speed=args.speed,
    )
    setup = trial = None
    if condition is not None:
        setup = trial_setup_of(args, participant, condition, support, reference, subject, catalogue)
    if args.record is not None:
        assert setup is not None  # a recorded trial has a condition (checked above)
        trial = trial_info(args, setup, reference, getattr(controller, "compensation", None), model)
        record_participant(args.record, participant, subject, args.hand_load)
    return _Prepared(suit, real_suit, participant, condition, reference, model, slack, controller, setup,
                     trial)


def _execute(args: argparse.Namespace, prepared: _Prepared) -> _Outcome:
    """Open the suit, run the trial, record it; the recording is closed whatever happens."""
    # The recorder (and its pandas) is imported only for a run that records: not for bowden run --help.
    from bowden.runtime.recorder import Recorder

    p = prepared
    with ExitStack() as stack:
        server = stack.enter_context(_serving(args, p.model)) if args.serve else None
        recorder = Recorder(args.record, p.trial).start() if p.trial is not None else None
        sync = _trial_sync(args, stack, recorder, p.reference, p.participant, p.condition)
        report: LoopReport | None = None
        backend: Backend | None = None
        error = "the run did not finish"
        recording_error = ""
        try:
            opener = (open_sim_backend(reference=p.reference, announce=_say, motor=p.suit.motor,
                                       firmware=p.suit.firmware, motor_id=p.suit.motor_id,
                                       imu_lsl_name=parse_imu(p.suit.imu))
                      if p.real_suit is None else open_can_backend(p.real_suit))
            backend = stack.enter_context(opener)
            print(f"bowden run: {backend.describe}", file=sys.stderr)
            report = run_trial(args, backend, recorder, controller=p.controller, reference=p.reference,
                               setup=p.setup, server=server, slack=p.slack, sync=sync)
            error = ""
            if recorder is not None:
                fault = report.fault.name if report.fault else "NONE"
                recorder.event(
                    report.stop_time_s, "safe_stop" if report.clean else "fault", f"{fault}: {report.reason}"
                )
        except BowdenError as exc:
            error = str(exc)
            raise
        finally:
            if recorder is not None:
                try:
                    recorder.close(stop_reason=report.reason if report is not None else f"error: {error}")
                except StoreError as exc:
                    if report is None:
                        raise
                    recording_error = str(exc)  # said in the summary; the stop stays the exit code
            if server is not None:
                server.web.manager.detach(report, error or None)
    return _Outcome(report, backend, recorder, sync, recording_error)


def _summarise(args: argparse.Namespace, prepared: _Prepared, outcome: _Outcome) -> None:
    """The run's summary on stdout: the stop, the safe state, timing, health, sync, the recording."""
    report, backend, recorder, sync = outcome.report, outcome.backend, outcome.recorder, outcome.sync
    print(f"stopped: {report.reason} ({report.fault.name if report.fault else 'no fault'})")
    ramp_ms = 1e3 * (report.zero_torque_time_s - report.stop_time_s)
    exited = "exited" if report.motor_disabled else "NOT confirmed exited"
    print(f"safe state: torque zero {ramp_ms:.0f} ms after the stop, motor mode {exited}")
    exit_error = getattr(backend.motor, "exit_error", None) if backend is not None else None
    if exit_error:
        print(f"motor: {exit_error}")
    if prepared.slack is not None:
        taken = (f"in {report.slack_take_up_s:.2f} s" if report.slack_take_up_s == report.slack_take_up_s
                 else "not completed")
        print(f"slack take-up: {taken}")
    print(f"loop timing: {report.timing.describe()}")
    print(f"health: {report.describe_health()}")
    if report.realtime:
        print(f"real-time settings: {report.realtime}")
    if sync is not None and sync.error is not None:
        print(f"sync: the trigger failed ({sync.error}); this trial has no sync events")
    elif sync is not None and sync.trigger is not None:
        for line in _trigger_report(sync.edge_uncertainties_s):
            print(line)
    if recorder is not None:
        _summarise_recording(args, recorder, outcome.recording_error)


def _summarise_recording(args: argparse.Namespace, recorder: Recorder, recording_error: str) -> None:
    gap_ms = 1e3 * recorder.stats.max_commit_gap_s
    print(
        f"recorded {recorder.stats.committed_rows} cycles into {args.record} "
        f"(trial {recorder.trial_id}, longest gap between commits {gap_ms:.0f} ms)"
    )
    if recorder.stats.rejected_rows:
        print(f"recording: {recorder.stats.rejected_rows} cycle(s) could not be stored and were dropped "
              "(the trial's rows_dropped events say why)")
    if recorder.stats.dropped_rows:
        print(f"recording: {recorder.stats.dropped_rows} cycle(s) were not written: the recording failed")
    if recording_error:
        print(f"recording: {recording_error}")
