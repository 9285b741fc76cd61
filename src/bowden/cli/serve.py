"""``bowden serve``: the participant display, operator console and questionnaires in the browser.

Prints the addresses and the session token, then serves until Ctrl-C (which stops a running trial
safely first). Trials started from the console run on the simulated suit (``--backend sim``: a
virtual participant follows the reference, paced to wall time) or on the real suit (``--backend
can``: the AK60-6 over CAN, the NGIMU over OSC/UDP and optionally the ADS1115 load cell, opened for
each trial with the same options and code as ``bowden run --backend can``; the arm hangs still for
the IMU calibration when a trial starts). With ``--trigger`` and ``--lsl`` every console trial pulses
the trigger line and publishes its LSL markers and samples, as ``bowden run`` does
(:mod:`bowden.cli._sync_options`). Needs the ``web`` extra.
"""

from __future__ import annotations

import argparse
import functools
import logging
import math
import sys
from collections.abc import Iterator, Mapping
from contextlib import ExitStack, contextmanager
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Final

from bowden.cli._flag_errors import flag_errors
from bowden.cli._loop_options import add_safety_arguments, realtime_config, safety_config, slack_config
from bowden.cli._outputs import check_output_file
from bowden.cli._protocol_options import add_protocol_arguments
from bowden.cli._suit import (
    CanSuitOptions,
    add_can_arguments,
    open_can_backend,
    require_hardware_extra,
)
from bowden.cli._sync_options import SyncOutputs, add_sync_arguments, open_sync_outputs
from bowden.cli.check import preflight_report
from bowden.contracts import BACKEND_CAN, REPETITIONS_PER_TRIAL, SPEEDS
from bowden.errors import ParameterError
from bowden.hardware.device_record import device_record
from bowden.model.model_file import load_model
from bowden.protocol.catalogue import catalogue_of
from bowden.protocol.session_plan import MAX_BREAK_S, ORDERS, PAPER_BREAK_S, StudyProtocol
from bowden.store.schema import STORE_FILE_NAME

if TYPE_CHECKING:
    from bowden.runtime import Recorder
    from bowden.runtime.trial_sync import TrialSync
    from bowden.web.server import ServeConfig
    from bowden.web.suits import OpenSuit, SuitBackend
    from bowden.web.trial_setup import TrialSetup


_PAPER_CONDITIONS = StudyProtocol().conditions
# bowden --help marks the command, and running it is one line, while this extra is missing.
EXTRA = ("web", ("starlette", "uvicorn", "websockets"))


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "serve",
        help="serve the participant display, operator console and questionnaires",
        description=(
            "Serve the study pages: /display (participant, read-only), /console (operator: start and "
            "stop trials, live plots, loop health) and /questionnaire. Operator actions need the "
            "session token printed at start. Trials run on the simulated suit (--backend sim) or on "
            "the real one (--backend can); --trigger and --lsl synchronise each with an EMG amplifier."
        ),
    )
    parser.add_argument(
        "--store", type=Path, default=Path(STORE_FILE_NAME),
        help=f"study store file (default {STORE_FILE_NAME}, the name bowden analyze looks for)",
    )
    plan = parser.add_argument_group("session plans (the paper's protocol by default)")
    plan.add_argument("--order", choices=ORDERS, default="random",
                      help="order of the support conditions after no suit: drawn from each session's "
                      "seed (random, default) or counterbalanced over participants (latin_square)")
    plan.add_argument("--conditions", default=",".join(_PAPER_CONDITIONS),
                      help="the conditions ordered after no suit, the paper's or --define-condition's "
                      f"(default {','.join(_PAPER_CONDITIONS)})")
    plan.add_argument("--speeds", default=",".join(SPEEDS),
                      help="speeds of every condition, in order, the paper's or --define-speed's "
                      f"(default {','.join(SPEEDS)})")
    add_protocol_arguments(plan)
    plan.add_argument("--repetitions", type=int, default=REPETITIONS_PER_TRIAL,
                      help=f"repetitions per trial (default {REPETITIONS_PER_TRIAL})")
    plan.add_argument("--lead-in", type=float, default=2.0,
                      help="rest before each reference moves, s (default 2)")
    plan.add_argument("--break-min", type=float, default=PAPER_BREAK_S / 60.0,
                      help="break with the questionnaires after each condition, minutes (default 5)")
    parser.add_argument("--model", type=Path,
                        help="compensation model (model.json) of the suit (required for --backend can)")
    parser.add_argument(
        "--friction-k",
        type=float,
        help="sim without --model: ideal single-bend model with this k = mu*sin(phi/2) "
        "(default: the simulated suit's sheath k)",
    )
    parser.add_argument("--backend", choices=("sim", "can"), default="sim",
                        help="where trials run: the simulated suit (default) or the real one over CAN")
    parser.add_argument(
        "--time-scale", type=float, default=1.0, help="sim: simulated seconds per wall second (default 1)"
    )
    parser.add_argument("--rate-hz", type=float, default=500.0, help="control rate (default 500 Hz)")
    parser.add_argument(
        "--host",
        default="127.0.0.1",
        help="address to listen on (default 127.0.0.1: this machine only)",
    )
    parser.add_argument("--port", type=int, default=8765, help="port (default 8765; 0 picks a free one)")
    add_sync_arguments(parser, trials="each trial started from the console")
    add_safety_arguments(parser)
    add_can_arguments(parser)
    parser.set_defaults(handler=run)


def can_backend(options: CanSuitOptions) -> SuitBackend:
    """The real suit for the console's trials: each trial opens it, calibrates, and closes it after."""
    from bowden.web.suits import ContextBackend, OpenSuit

    @contextmanager
    def open_suit(setup: TrialSetup) -> Iterator[OpenSuit]:
        with open_can_backend(options, announce=logging.getLogger(__name__).info) as backend:
            yield OpenSuit(motor=backend.motor, elevation_sensor=backend.imu, clock=backend.clock,
                           tension_sensor=backend.load_cell, description=backend.describe,
                           devices=device_record(options.motor, options.firmware, options.imu))

    return ContextBackend(BACKEND_CAN, open_suit)


# The names the runtime's refusals use for what serve takes from a flag in the same unit (the flags
# in ms and minutes are checked before they are converted: _checked_units, safety_config).
_FLAGS: Final = {
    "ServeConfig.port": "--port",
    "ServeConfig.host": "--host",
    "LoopConfig.rate_hz": "--rate-hz",
    "time_scale": "--time-scale",
    "SlackTakeUp.timeout_s": "--slack-timeout",
    "StudyProtocol.conditions": "--conditions",
    "StudyProtocol.speeds": "--speeds",
    "StudyProtocol.repetitions": "--repetitions",
    "StudyProtocol.lead_in_s": "--lead-in",
    "StudyProtocol.order": "--order",
}


def serve_config(args: argparse.Namespace) -> ServeConfig:
    """What ``bowden serve`` runs, from its arguments; checked before anything is opened.

    Raises
    ------
    BowdenError
        If the web (or, for ``--backend can``, the hardware) extra is missing, or an option is wrong
        (one line naming the flag).
    """
    _checked_units(args)
    with flag_errors(_FLAGS):
        return _serve_config(args)


def _checked_units(args: argparse.Namespace) -> None:
    """The flags whose fields have another unit or meaning, checked as the user typed them.

    (The watchdogs' ms flags and the real-time flags are checked so by ``_loop_options``; the
    real-time ones here too, although only the real suit's trials use them.)
    """
    max_break_min = MAX_BREAK_S / 60.0
    if not (math.isfinite(args.break_min) and 0.0 <= args.break_min <= max_break_min):
        raise ParameterError(f"--break-min must be 0–{max_break_min:g} min, got {args.break_min:g}")
    realtime_config(args)
    if args.friction_k is not None:
        from bowden.model import CompensationModel

        try:
            CompensationModel.from_friction(k=args.friction_k)
        except ParameterError as error:
            raise ParameterError(f"--friction-k: {error}") from None


def _serve_config(args: argparse.Namespace) -> ServeConfig:
    try:
        from bowden.web.server import ServeConfig
        from bowden.web.suits import SimulatedBackend
    except ImportError as error:  # the extra is there but incomplete (EXTRA checks its main modules)
        from bowden.cli import missing_extra_error

        raise missing_extra_error("bowden serve", "web", [error.name or str(error)]) from None
    from bowden.model import CompensationModel
    from bowden.runtime import LoopConfig

    # Said now, in the flag's words (SQLite says "unable to open database file"); the store is made
    # in an existing folder.
    check_output_file("the study store (--store)", args.store, create_parents=False)
    safety = safety_config(args)
    LoopConfig(rate_hz=args.rate_hz, safety=safety)  # refused now, not at the first trial
    backend: SuitBackend
    realtime = None  # the simulated suit's trials run on their own paced clock
    if args.backend == "can":
        realtime = realtime_config(args)
        if args.model is None:
            raise ParameterError("--backend can needs --model model.json (run `bowden identify` first)")
        options = CanSuitOptions.from_args(args)
        require_hardware_extra("bowden serve", options)
        backend = can_backend(options)
    else:
        suit = CanSuitOptions.from_args(args)  # --motor, --firmware and --imu count on either backend
        backend = SimulatedBackend(time_scale=args.time_scale, motor=suit.motor, firmware=suit.firmware,
                                   imu=suit.imu)
    if args.model is not None:
        model = load_model(args.model)
    else:
        k = args.friction_k if args.friction_k is not None else _sim_friction_k()
        model = CompensationModel.from_friction(k=k)
    slack = slack_config(args, model.pulley_radius_m)
    protocol = session_protocol(args)
    from bowden.web.store_catalogue import checked_catalogue

    checked_catalogue(args.store, protocol.catalogue)  # a name the store gave another meaning: refused now
    return ServeConfig(store_path=args.store, model=model, model_file=args.model, backend=backend,
                       host=args.host, port=args.port,
                       rate_hz=args.rate_hz, safety=safety, realtime=realtime, slack=slack,
                       protocol=protocol, preflight=functools.partial(preflight_report, args))


def session_protocol(args: argparse.Namespace) -> StudyProtocol:
    """The protocol of the session plans, from the flags (errors name the flag).

    The store's own definitions are checked against ``--define-condition`` and ``--define-speed``
    when the server opens it (:class:`bowden.web.session_desk.SessionDesk`).
    """
    speeds = tuple(s.strip() for s in args.speeds.split(",") if s.strip())
    conditions = tuple(c.strip() for c in args.conditions.split(",") if c.strip())
    catalogue = catalogue_of(args.define_condition, args.define_speed)
    with flag_errors(_FLAGS):
        return StudyProtocol(conditions=conditions, speeds=speeds, repetitions=args.repetitions,
                             lead_in_s=args.lead_in, break_s=60.0 * args.break_min, order=args.order,
                             catalogue=catalogue)


def run(args: argparse.Namespace) -> int:
    config = serve_config(args)
    from bowden.web.server import serve

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    with ExitStack() as stack:  # the trigger line and the outlets stay open while the server runs
        serve(synced(config, args, stack))
    return 0


def synced(config: ServeConfig, args: argparse.Namespace, stack: ExitStack) -> ServeConfig:
    """``config`` with the trigger line and LSL outlets of ``--trigger``/``--lsl`` (opened now, closed
    by ``stack``) driven by every console trial; ``config`` itself when neither is asked."""
    outputs = open_sync_outputs(args, stack, rate_hz=args.rate_hz, say=_say)
    if outputs is None:
        return config
    return replace(config, sync=ConsoleSync(outputs, config.store_path.name))


def _say(text: str) -> None:
    print(f"bowden serve: {text}", file=sys.stderr, flush=True)


class ConsoleSync:
    """The sync signals of each console trial, on the outputs ``--trigger``/``--lsl`` opened.

    Implements :class:`bowden.web.trial_signals.TrialSyncs`: the session marker carries the participant,
    condition, speed and store, and for a trial of a plan its session and position.
    """

    def __init__(self, outputs: SyncOutputs, store_name: str) -> None:
        self.outputs = outputs
        self.store_name = store_name

    def start(self, setup: TrialSetup, recorder: Recorder, metadata: Mapping[str, object]) -> TrialSync:
        session: dict[str, object] = {
            "participant": setup.participant,
            "condition": setup.condition,
            "speed": setup.speed,
            "store": self.store_name,
        }
        session.update({k: metadata[k] for k in ("session_id", "plan_position") if k in metadata})
        return self.outputs.trial(trial_id=recorder.trial_id, on_event=recorder.event,
                                  reference=setup.reference, session=session)

    def ended(self, sync: TrialSync) -> list[str]:
        return self.outputs.ended(sync)


def _sim_friction_k() -> float:
    from bowden.sim.parameters import SuitParameters

    return SuitParameters().sheath.kinetic_coefficient
