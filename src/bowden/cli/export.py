"""``bowden export --bids DIR [STORE]``: a study store as a BIDS dataset.

docs/study.md, "Share the study".
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path
from typing import Final

from bowden.cli._outputs import check_output_directory
from bowden.errors import ParameterError, StoreError
from bowden.store.schema import STORE_FILE_NAME

EXTRA: Final = ("share", ("edfio",))
# An SPDX licence identifier or expression's characters (https://spdx.org/licenses/): CC-BY-4.0,
# CC0-1.0, "CC-BY-4.0 OR MIT".
_SPDX: Final = re.compile(r"[A-Za-z0-9][A-Za-z0-9.+-]*(?: (?:AND|OR|WITH) [A-Za-z0-9][A-Za-z0-9.+-]*)*")


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "export",
        help="export a study store as a BIDS dataset (EMG, motion, loop signals, events)",
        description="Write every trial of a study store as a BIDS 1.11 dataset: the sEMG as EDF+/BDF+ "
        "(the stored codes, exactly), the IMU elevation as motion, the loop's signals as physio, the trials "
        "as events, participants.tsv and the questionnaires under phenotype/.",
    )
    parser.add_argument(
        "store",
        nargs="?",
        type=Path,
        default=Path(STORE_FILE_NAME),
        help=f"study directory or store file (default: {STORE_FILE_NAME} here)",
    )
    parser.add_argument(
        "--bids",
        type=Path,
        metavar="DIR",
        required=True,
        help="the dataset's directory (new, empty, or a previous bowden export)",
    )
    parser.add_argument(
        "--power-line-hz",
        type=float,
        metavar="HZ",
        help="mains frequency where the EMG was recorded (50 or 60; default: n/a)",
    )
    parser.add_argument(
        "--authors",
        action="append",
        metavar="NAME",
        default=[],
        help="an author of the dataset (dataset_description.json Authors); repeat for each, in order",
    )
    parser.add_argument(
        "--license",
        metavar="SPDX",
        help="the dataset's licence as an SPDX identifier, e.g. CC-BY-4.0 or CC0-1.0 (default: none stated)",
    )
    parser.add_argument(
        "--manufacturer",
        metavar="NAME",
        help="maker of the EMG amplifier, for recorded EMG whose import did not name it (e.g. TMSi)",
    )
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    store = args.store / STORE_FILE_NAME if args.store.is_dir() else args.store
    if not store.is_file():
        raise StoreError(
            f"no study store at {store} (a study directory holding {STORE_FILE_NAME}, or a store file)"
        )
    hz = args.power_line_hz
    if hz is not None and hz not in (50.0, 60.0):  # the mains is one or the other: 55 is a typo
        raise ParameterError(f"--power-line-hz must be 50 or 60 (the mains frequency), got {hz:g}")
    authors = tuple(name.strip() for name in args.authors)
    if any(not name for name in authors):
        raise ParameterError("--authors needs a name (an empty one was given)")
    if args.license is not None and not _SPDX.fullmatch(args.license):
        raise ParameterError(
            f"--license must be an SPDX licence identifier such as CC-BY-4.0 or CC0-1.0, got {args.license!r}"
        )
    manufacturer = args.manufacturer.strip() if args.manufacturer else None
    check_output_directory("the dataset (--bids)", args.bids)
    from bowden.share.bids import BidsOptions, export_bids
    from bowden.store.study_store import StudyStore

    options = BidsOptions(
        power_line_hz=hz, authors=authors, license_id=args.license, manufacturer=manufacturer or None
    )
    with StudyStore(store) as opened:
        written = export_bids(opened, args.bids, options)
    sessions = ", each session as ses-" if written.sessions else ""
    print(
        f"exported {written.runs} trials of {written.subjects} participants ({written.emg_runs} with sEMG"
        f"{sessions}) as BIDS to {written.directory}"
    )
    return 0
