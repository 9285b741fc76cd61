"""``bowden serve``: the participant display, operator console and questionnaires in the browser.

Prints the addresses and the session token, then serves until Ctrl-C (which stops a running trial
safely first). Trials run on the simulated suit (a virtual participant follows the reference, paced
to wall time); the real suit is driven by ``bowden run``. Needs the ``web`` extra.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from bowden.errors import BowdenError


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "serve",
        help="serve the participant display, operator console and questionnaires",
        description=(
            "Serve the study pages: /display (participant, read-only), /console (operator: start and "
            "stop trials, live plots, loop health) and /questionnaire. Operator actions need the "
            "session token printed at start."
        ),
    )
    parser.add_argument(
        "--store", type=Path, default=Path("study.sqlite"), help="study store file (default study.sqlite)"
    )
    parser.add_argument("--model", type=Path, help="compensation model (model.json) of the suit")
    parser.add_argument(
        "--friction-k",
        type=float,
        default=0.12,
        help="without --model: ideal single-bend model with this k = mu*sin(phi/2) (default 0.12)",
    )
    parser.add_argument("--backend", choices=("sim",), default="sim", help="where trials run (sim)")
    parser.add_argument(
        "--time-scale", type=float, default=1.0, help="simulated seconds per wall second (default 1)"
    )
    parser.add_argument("--rate-hz", type=float, default=500.0, help="control rate (default 500 Hz)")
    parser.add_argument(
        "--host",
        default="127.0.0.1",
        help="address to listen on (default 127.0.0.1: this machine only)",
    )
    parser.add_argument("--port", type=int, default=8765, help="port (default 8765; 0 picks a free one)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    try:
        from bowden.web.server import ServeConfig, serve
        from bowden.web.suits import SimulatedBackend
    except ImportError as error:
        raise BowdenError(
            f"bowden serve needs the web extra ({error.name} is missing): pip install 'bowden[web]'"
        ) from None
    from bowden.model import CompensationModel

    model = (
        CompensationModel.load(args.model)
        if args.model is not None
        else CompensationModel.from_friction(k=args.friction_k)
    )
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    config = ServeConfig(
        store_path=args.store,
        model=model,
        backend=SimulatedBackend(time_scale=args.time_scale),
        host=args.host,
        port=args.port,
        rate_hz=args.rate_hz,
    )
    serve(config)
    return 0
