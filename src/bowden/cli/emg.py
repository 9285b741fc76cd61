"""``bowden emg import STORE RECORDING...``: an amplifier's sEMG recordings into a study store.

Each recording (EDF/BDF, XDF from LabRecorder, or CSV) is placed on the controller's clock from the
trigger pulses that ``bowden run --trigger`` sent (``--trigger-channel``) or, in an XDF file, from
bowden's LSL markers; offset and drift are fitted over all of them and the residuals reported. Every
channel is checked, and each recording is written in one transaction or not at all, keeping the file's
own samples (EDF/BDF codes, XDF/CSV numbers). A CSV has a time_s column (s, evenly spaced) and one
column per channel (--csv-volts-per-unit says its unit). Importing a file again is a no-op; another
file for a trial that has EMG is refused unless ``--replace``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from bowden.analysis.emg.constants import (
    BUILT_IN_MAPPINGS,
    DRIFT_TOLERANCE_PPM,
    POLARITIES,
    RESIDUAL_TOLERANCE_S,
)
from bowden.contracts import EMG_RATE_HZ


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser("emg", help="sEMG recordings of a study: import them into the store")
    commands = parser.add_subparsers(title="emg commands", metavar="COMMAND", dest="emg_command")
    imp = commands.add_parser(
        "import",
        help="import amplifier recordings (EDF/BDF, XDF, CSV) into a study store",
        description=__doc__.split("\n\n")[1] if __doc__ else None,
    )
    imp.add_argument("store", type=Path, help="study store (study.db, or the study directory)")
    imp.add_argument("recordings", type=Path, nargs="+", metavar="RECORDING", help=".edf .bdf .xdf .csv")
    imp.add_argument(
        "--trigger-channel",
        metavar="NAME",
        help="channel holding bowden's trigger line (EDF/BDF/CSV; e.g. TRIGGERS on a TMSi SAGA); "
        "XDF files use bowden's LSL markers unless this is given",
    )
    imp.add_argument(
        "--trigger-polarity",
        choices=POLARITIES,
        default="auto",
        help="high: the trigger channel idles low and a trial is a high pulse; low: it idles high and a "
        "trial is a low pulse (negative logic, as the TMSi SAGA's TRIGGER port records); auto (default): "
        "from its level at the recording's start and end",
    )
    imp.add_argument(
        "--trigger-bit",
        type=int,
        metavar="N",
        help="read bit N (0 = least significant) of the trigger channel's integer value: a trigger word "
        "whose other bits other devices drive (default: the whole value)",
    )
    imp.add_argument(
        "--channels",
        metavar="MAP",
        help="JSON file mapping the recording's labels to muscles, or "
        f"{' / '.join(BUILT_IN_MAPPINGS)} (default: the labels are muscle names)",
    )
    imp.add_argument("--replace", action="store_true", help="replace EMG the trials already have")
    imp.add_argument(
        "--max-drift-ppm",
        type=float,
        default=DRIFT_TOLERANCE_PPM,
        help=f"largest accepted clock drift, ppm (default {DRIFT_TOLERANCE_PPM:g})",
    )
    imp.add_argument(
        "--max-residual-ms",
        type=float,
        default=1e3 * RESIDUAL_TOLERANCE_S,
        help=f"largest accepted sync residual, ms (default {1e3 * RESIDUAL_TOLERANCE_S:g})",
    )
    imp.add_argument(
        "--rate", type=float, default=EMG_RATE_HZ, help=f"expected EMG rate, Hz (default {EMG_RATE_HZ:g})"
    )
    imp.add_argument(
        "--csv-volts-per-unit", type=float, default=1.0, help="CSV unit in volts (1e-6 for µV; default 1)"
    )
    imp.set_defaults(handler=run_import)

    def usage(args: argparse.Namespace) -> int:
        parser.print_help()
        return 2

    parser.set_defaults(handler=usage)


def run_import(args: argparse.Namespace) -> int:
    # Imported here, not at the top: building the parser (bowden --help) needs none of the EMG stack.
    from bowden.analysis.emg.channels import load_channel_map
    from bowden.study.emg.importer import ImportOptions, import_emg

    store = args.store / "study.db" if args.store.is_dir() else args.store
    options = ImportOptions(
        trigger_channel=args.trigger_channel,
        trigger_polarity=args.trigger_polarity,
        trigger_bit=args.trigger_bit,
        channel_map=load_channel_map(args.channels) if args.channels is not None else None,
        replace=args.replace,
        drift_tolerance_ppm=args.max_drift_ppm,
        residual_tolerance_s=args.max_residual_ms * 1e-3,
        expected_rate_hz=args.rate,
        csv_volts_per_unit=args.csv_volts_per_unit,
    )
    for recording in args.recordings:
        result = import_emg(store, recording, options)
        print(result.describe())
    return 0
