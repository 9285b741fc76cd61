"""The flags of a lab's own conditions and speeds, the same in ``bowden serve`` and ``bowden run``."""

from __future__ import annotations

import argparse
from pathlib import Path

from bowden.protocol.catalogue import Catalogue, catalogue_of


def add_protocol_arguments(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """``--define-condition NAME=SUPPORT`` and ``--define-speed NAME=DEG_S`` (each repeatable)."""
    parser.add_argument(
        "--define-condition", action="append", metavar="NAME=SUPPORT",
        help="a condition of your own and its support fraction or percent, e.g. support_70=0.7 "
        "(repeatable; names: a letter, then letters, digits or underscores; the paper's keep theirs)",
    )
    parser.add_argument(
        "--define-speed", action="append", metavar="NAME=DEG_S",
        help="a speed of your own and its reference's peak elevation speed in deg/s, e.g. V4=240 "
        "(repeatable; 10-400 deg/s)",
    )


def protocol_catalogue(args: argparse.Namespace, store: Path | None) -> Catalogue:
    """The flags' definitions, with those ``store`` recorded (a name given another meaning is refused)."""
    catalogue = catalogue_of(args.define_condition, args.define_speed)
    if store is None:
        return catalogue
    from bowden.web.store_catalogue import checked_catalogue  # cli wires web and the protocol

    return checked_catalogue(store, catalogue)
