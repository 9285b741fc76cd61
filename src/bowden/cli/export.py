"""``bowden export --bids DIR [STORE]``: a study store as a BIDS dataset.

docs/study.md, "Share the study".
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Final

from bowden.cli._outputs import check_output_directory
from bowden.errors import ParameterError, StoreError
from bowden.store.schema import STORE_FILE_NAME

EXTRA: Final = ("share", ("edfio",))


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
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    store = args.store / STORE_FILE_NAME if args.store.is_dir() else args.store
    if not store.is_file():
        raise StoreError(
            f"no study store at {store} (a study directory holding {STORE_FILE_NAME}, or a store file)"
        )
    hz = args.power_line_hz
    if hz is not None and not (math.isfinite(hz) and hz > 0):
        raise ParameterError(f"--power-line-hz must be a positive frequency, got {hz}")
    check_output_directory("the dataset (--bids)", args.bids)
    from bowden.share.bids import export_bids
    from bowden.store.study_store import StudyStore

    with StudyStore(store) as opened:
        written = export_bids(opened, args.bids, power_line_hz=hz)
    print(
        f"exported {written.runs} trials of {written.subjects} participants ({written.emg_runs} with sEMG) "
        f"as BIDS to {written.directory}"
    )
    return 0
