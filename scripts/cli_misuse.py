"""Run ``bowden`` the way a hurried lab would misuse it, and flag every answer that breaks the rule.

The project's rule for bad input: one line on stderr naming the problem with the command's own flags,
a non-zero exit code, no traceback, no internal name (``duration_s``, ``LoopConfig``), and no
recording or output that existed before the run modified or deleted. Each case runs ``bowden`` in a
subprocess (with a timeout: nothing here may run a long simulation or a real-time loop to its end)
against fixtures made in a temporary directory; nothing touches real hardware (``--backend can``
fails to open the bus, and that failure must be one line too).

Usage: ``python scripts/cli_misuse.py [-k SUBSTRING] [--show]``; the exit code is 1 when a case is
flagged. ``--show`` prints every case's stderr line.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import re
import shutil
import sqlite3
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

BOWDEN = Path(sys.executable).with_name("bowden")
TIMEOUT_S = 25.0
# snake_case attribute names with a unit suffix, or ClassName.field: the internal names a user never typed.
INTERNAL_NAME = re.compile(
    r"\b[a-z]+(?:_[a-z0-9]+)*_(?:s|hz|ms|n|nm|m|rad|deg|kg|ppm)\b|\b[A-Z][a-z]+[A-Z]\w*\.\w+"
)
# Words of that shape that users do type: a bench recording's columns, a model file's fields.
ALLOWED = {"time_s", "tension_n", "motor_torque_nm", "elevation_rad", "motor_velocity_rad_s",
           "mannequin_elevation_rad", "law_tension_n", "slope_m", "intercept_nm"}
# A bare field name opening the message ("seed must be ...", "speeds: unknown ..."): not a flag's spelling.
BARE_FIELD = re.compile(r"error: ([a-z][a-z0-9_]*)(?: must|: unknown value)")


@dataclass
class Case:
    """One misuse: ``argv`` (``{d}`` is the fixture directory) and the files it must leave alone."""

    argv: str
    protect: tuple[str, ...] = ()
    expect_fail: bool = True
    allow_internal: bool = False
    says: str = ""  # what the refusal must say (the flag's problem, not another input's)
    flags: list[str] = field(default_factory=list)


def make_fixtures(d: Path) -> None:
    """Every file the cases name: good inputs to misuse, bad inputs, and outputs that must survive."""
    (d / "adir").mkdir()
    (d / "empty.csv").write_bytes(b"")
    (d / "empty.json").write_bytes(b"")
    (d / "empty.db").write_bytes(b"")
    (d / "img.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4)
    (d / "other.csv").write_text("a,b,c\n1,2,3\n4,5,6\n")
    header = "time_s,motor_torque_nm,motor_velocity_rad_s,tension_n,elevation_rad"
    extra = "".join(f",extra{i}" for i in range(9))
    (d / "wide.csv").write_text(f"{header}{extra}\n0,0,0,0,0{',1' * 9}\n")
    (d / "corrupt.parquet").write_bytes(b"PAR1" + os.urandom(300) + b"PAR1")
    (d / "corrupt.db").write_bytes(b"SQLite format 3\x00" + os.urandom(5000))
    with sqlite3.connect(d / "foreign.db") as conn:
        conn.execute("create table t (x integer)")
    (d / "existing.txt").write_text("a recording that must survive\n")
    from bowden.store.study_store import StudyStore

    with StudyStore(d / "store.db"):  # an empty bowden store, as bowden makes one
        pass
    subprocess.run([str(BOWDEN), "bench", "simulate", "-o", str(d / "bench.csv"), "--speeds", "1", "2",
                    "--loads", "1", "2", "--repetitions", "1", "--quiet"], check=True, capture_output=True)
    shutil.copy(d / "bench.csv", d / "bench_copy.csv")
    subprocess.run([str(BOWDEN), "identify", str(d / "bench.csv"), "-o", str(d / "model.json"),
                    "--paper-only"], check=True, capture_output=True)
    model = json.loads((d / "model.json").read_text())
    broken = dict(model)
    broken.pop("raising")
    (d / "model_missing.json").write_text(json.dumps(broken))
    nan = json.loads(json.dumps(model))
    nan["raising"]["slope_m"] = math.nan
    (d / "model_nan.json").write_text(json.dumps(nan))
    negative = json.loads(json.dumps(model))
    negative["lowering"]["slope_m"] = -0.03
    (d / "model_negative.json").write_text(json.dumps(negative))
    (d / "model_list.json").write_text("[1, 2, 3]")
    (d / "fake.edf").write_bytes(b"0       " + bytes(300))
    (d / "fake.xdf").write_bytes(b"XDF:" + bytes(100))
    (d / "bad.toml").write_text("this is = = not toml\n")
    (d / "channels_bad.json").write_text('{"ch1": 5}')


CASES: list[Case] = [
    # analyze
    Case("analyze {d}/missing.db"),
    Case("analyze {d}/adir"),
    Case("analyze {d}/empty.db"),
    Case("analyze {d}/img.png"),
    Case("analyze {d}/corrupt.db"),
    Case("analyze {d}/foreign.db"),
    Case("analyze {d}/foreign.db --workers 0"),
    Case("analyze {d}/foreign.db --workers abc"),
    Case("analyze {d}/foreign.db --report {d}/foreign.db", protect=("foreign.db",)),
    Case("analyze {d}/foreign.db --report {d}/nodir/sub/r.html"),
    Case("analyze {d}/foreign.db --report /proc/r.html"),
    Case("analyze {d}/foreign.db --bench {d}/img.png"),
    Case("analyze {d}/foreign.db --export {d}/existing.txt", protect=("existing.txt",)),
    # check
    Case("check --backend can --channel vcan_nonexistent"),
    Case("check --backend sim --model {d}/missing.json"),
    Case("check --backend sim --model {d}/adir"),
    Case("check --backend sim --model {d}/empty.json"),
    Case("check --backend sim --model {d}/img.png"),
    Case("check --backend sim --model {d}/model_missing.json"),
    Case("check --backend sim --model {d}/model_nan.json"),
    Case("check --backend sim --model {d}/model_negative.json"),
    Case("check --backend sim --model {d}/model_list.json"),
    Case("check --backend sim --rate 0"),
    Case("check --backend sim --rate nan"),
    Case("check --backend sim --imu-rate -5"),
    Case("check --backend sim --session-min inf"),
    Case("check --backend sim --record {d}/corrupt.db", protect=("corrupt.db",)),
    Case("check --backend sim --record {d}/img.png", protect=("img.png",)),
    Case("check --backend sim --inject nonsense"),
    Case("check --backend sim --calibration-s -1"),
    Case("check --backend sim --load-cell-gain nan"),
    Case("check --backend sim --motor-id 999"),
    Case("check --backend sim --imu-port 70000"),
    # emg import
    Case("emg import {d}/missing.db {d}/bench.csv"),
    Case("emg import {d}/foreign.db {d}/missing.edf"),
    Case("emg import {d}/foreign.db {d}/img.png"),
    Case("emg import {d}/foreign.db {d}/adir"),
    Case("emg import {d}/corrupt.db {d}/other.csv", protect=("corrupt.db",)),
    Case("emg import {d}/foreign.db {d}/other.csv --rate 0", protect=("foreign.db",)),
    Case("emg import {d}/foreign.db {d}/other.csv --rate nan"),
    Case("emg import {d}/foreign.db {d}/other.csv --max-drift-ppm -1"),
    Case("emg import {d}/foreign.db {d}/other.csv --trigger-bit -1"),
    Case("emg import {d}/foreign.db {d}/other.csv --csv-volts-per-unit 0"),
    Case("emg import {d}/foreign.db {d}/other.csv --channels {d}/img.png"),
    Case("emg import {d}/foreign.db {d}/other.csv --channels {d}/channels_bad.json"),
    Case("emg import {d}/img.png {d}/other.csv", protect=("img.png",)),
    Case("emg import {d}/store.db {d}/other.csv --rate 0", protect=("store.db",)),
    Case("emg import {d}/store.db {d}/other.csv --rate inf"),
    Case("emg import {d}/store.db {d}/other.csv --max-drift-ppm -1"),
    Case("emg import {d}/store.db {d}/other.csv --max-residual-ms nan"),
    Case("emg import {d}/store.db {d}/other.csv --trigger-bit -1"),
    Case("emg import {d}/store.db {d}/other.csv --trigger-bit 99"),
    Case("emg import {d}/store.db {d}/other.csv --csv-volts-per-unit 0"),
    Case("emg import {d}/store.db {d}/other.csv --csv-volts-per-unit nan"),
    Case("emg import {d}/store.db {d}/other.csv", protect=("store.db",)),
    Case("emg import {d}/store.db {d}/empty.csv", protect=("store.db",)),
    Case("emg import {d}/store.db {d}/img.png", protect=("store.db",)),
    Case("emg import {d}/store.db {d}/corrupt.parquet", protect=("store.db",)),
    Case("emg import {d}/store.db {d}/missing.edf", protect=("store.db",)),
    Case("emg import {d}/store.db {d}/fake.edf", protect=("store.db",)),
    Case("emg import {d}/store.db {d}/fake.xdf", protect=("store.db",)),
    # flags checked before the store or the recording is opened: neither exists here
    Case("emg import {d}/missing.db {d}/missing.edf --max-drift-ppm 0", says="--max-drift-ppm must"),
    Case("emg import {d}/missing.db {d}/missing.edf --max-drift-ppm inf", says="--max-drift-ppm must"),
    Case("emg import {d}/missing.db {d}/missing.edf --max-drift-ppm abc", says="--max-drift-ppm"),
    Case("emg import {d}/missing.db {d}/missing.edf --max-residual-ms -1", says="--max-residual-ms must"),
    Case("emg import {d}/missing.db {d}/missing.edf --csv-volts-per-unit=-1e-6",
         says="--csv-volts-per-unit must"),
    Case("emg import {d}/missing.db {d}/missing.edf --trigger-bit 32", says="--trigger-bit must"),
    # export
    Case("export {d}/store.db --bids {d}/out --power-line-hz 55"),
    Case("export {d}/store.db --bids {d}/out --power-line-hz -50"),
    Case("export {d}/store.db --bids {d}/store.db", protect=("store.db",)),
    Case("export {d}/store.db --bids {d}/adir/../store.db", protect=("store.db",)),
    Case("export {d}/store.db --bids /proc/bids"),
    Case("export {d}/store.db --bids {d}/out --authors ''"),
    Case("analyze {d}/store.db"),
    Case("analyze {d}/store.db --workers 0"),
    Case("analyze {d}/store.db --report {d}/store.db", protect=("store.db",)),
    Case("analyze {d}/store.db --export {d}/store.db", protect=("store.db",)),
    Case("analyze {d}/store.db --export-emg"),
    Case("analyze {d}/store.db --bench {d}/missing.parquet"),
    Case("analyze {d}/store.db --bench {d}/corrupt.parquet"),
    Case("analyze {d}/store.db --report {d}/r.txt"),
    Case("bench run -o {d}/br.csv --backend can --i2c-bus 99 --channel vcan_nonexistent"),
    Case("check --backend sim --record {d}/store.db --session-min 1e9"),
    # conflicting or pointless flags (a flag that does nothing here is silent garbage)
    Case("analyze {d}/store.db --format csv"),
    Case("run --backend sim --duration 0.2 --host 0.0.0.0"),
    Case("run --backend sim --duration 0.2 --port 9999"),
    Case("run --backend sim --duration 0.2 --condition no_suit --support 0.5"),
    Case("run --backend sim --duration 0.2 --compensation dynamic"),
    # Without --record there is no registry to contradict: --height is the wearer's.
    Case("run --backend sim --duration 0.2 --participant P01 --height 1.8", expect_fail=False),
    Case("bench validate {d}/model.json --resume"),
    Case("bench validate {d}/model.json --study-speeds V1 --support 0.5"),
    Case("bench validate {d}/model.json --study-repetitions 3 --support 0.5"),
    Case("bench validate {d}/model.json --bench-output {d}/v.csv --support 0.5"),
    Case("bench validate {d}/model.json --recording {d}/bench.csv --backend can"),
    Case("bench validate {d}/model.json --fit"),
    Case("bench run -o {d}/new.csv --backend sim --resume"),
    Case("bench run -o {d}/br.csv --backend sim --no-later-segments --chirp-s 5"),
    Case("emg import {d}/store.db {d}/other.csv --trigger-bit 3"),
    Case("emg import {d}/store.db {d}/other.csv --trigger-polarity low"),
    Case("identify {d}/bench.csv -o {d}/m.json --paper-only --study-recording {d}/bench.csv",
         says="--paper-only"),
    Case("identify {d}/bench.csv -o {d}/m.json --paper-only --latency-recording {d}/bench.csv"),
    Case("identify {d}/bench.csv -o {d}/m.json --paper-only --imu-latency-ms 30", says="--paper-only"),
    Case("identify {d}/bench.csv -o {d}/m.json --paper-only --imu-latency-ms 50", says="--paper-only"),
    Case("identify {d}/bench.csv -o {d}/m.json --imu-latency-ms 30 --latency-recording {d}/bench.csv",
         says="--imu-latency-ms and --latency-recording"),
    Case("study --quick-bench --force --out /proc/st"),
    Case("sweep blend-velocity --list --participants 0", expect_fail=False),  # --list prints and exits
    Case("export {d}/missing.db --bids {d}/out"),
    Case("export {d}/img.png --bids {d}/out"),
    Case("export {d}/corrupt.db --bids {d}/out"),
    Case("export {d}/foreign.db --bids {d}/existing.txt", protect=("existing.txt",)),
    Case("export {d}/foreign.db --bids {d}/out --power-line-hz 55"),
    Case("export {d}/foreign.db --bids {d}/out --power-line-hz nan"),
    Case("export {d}/foreign.db --bids {d}/out --license 'not a licence'"),
    # identify
    Case("identify {d}/missing.csv -o {d}/m.json"),
    Case("identify {d}/adir -o {d}/m.json"),
    Case("identify {d}/empty.csv -o {d}/m.json"),
    Case("identify {d}/img.png -o {d}/m.json"),
    Case("identify {d}/other.csv -o {d}/m.json", says="missing column(s) time_s"),
    Case("identify {d}/other.csv -o {d}/m.json --ignore-extra-columns", says="missing column(s) time_s"),
    Case("identify {d}/wide.csv -o {d}/m.json", says="and 5 more (give --ignore-extra-columns"),
    Case("identify {d}/corrupt.parquet -o {d}/m.json"),
    Case("identify {d}/bench.csv -o {d}/bench.csv", protect=("bench.csv",)),
    Case("identify {d}/bench.csv -o {d}/nodir/sub/m.json"),
    Case("identify {d}/bench.csv -o {d}/adir"),
    Case("identify {d}/bench.csv -o /proc/m.json"),
    Case("identify {d}/bench.csv -o {d}/m.json --pulley-radius-mm 0"),
    Case("identify {d}/bench.csv -o {d}/m.json --pulley-radius-mm nan"),
    Case("identify {d}/bench.csv -o {d}/m.json --cutoff-hz -5"),
    Case("identify {d}/bench.csv -o {d}/m.json --cutoff-hz inf"),
    Case("identify {d}/bench.csv -o {d}/m.json --min-samples 0"),
    Case("identify {d}/bench.csv -o {d}/m.json --min-elevation-deg 90 --max-elevation-deg 20"),
    Case("identify {d}/bench.csv -o {d}/m.json --imu-latency-ms -1"),
    Case("identify {d}/bench.csv -o {d}/m.json --figure {d}/fig.txt"),
    Case("identify {d}/bench.csv -o {d}/m.json --figure {d}/bench.csv", protect=("bench.csv",)),
    Case("identify {d}/bench.csv -o {d}/m.json --study-recording {d}/img.png"),
    Case("identify {d}/bench.csv -o {d}/m.json --latency-recording {d}/other.csv"),
    Case("identify {d}/bench.csv -o {d}/m.json --max-acceleration-deg-s2 abc"),
    # run (the sim backend with a zero-length or refused run only)
    Case("run --backend sim --support 5"),
    Case("run --backend sim --support -0.1"),
    Case("run --backend sim --support nan"),
    Case("run --backend sim --support abc"),
    Case("run --backend sim --duration nan"),
    Case("run --backend sim --duration -1"),
    Case("run --backend sim --duration 0"),
    Case("run --backend sim --duration inf"),
    Case("run --backend sim --rate 0"),
    Case("run --backend sim --rate -500"),
    Case("run --backend sim --rate 1e9"),
    Case("run --backend sim --model {d}/missing.json"),
    Case("run --backend sim --model {d}/adir"),
    Case("run --backend sim --model {d}/empty.json"),
    Case("run --backend sim --model {d}/img.png"),
    Case("run --backend sim --model {d}/model_missing.json"),
    Case("run --backend sim --model {d}/model_nan.json"),
    Case("run --backend sim --model {d}/model_negative.json"),
    Case("run --backend sim --model {d}/model_list.json"),
    Case("run --backend can"),
    Case("run --backend can --model {d}/model.json --channel vcan_nonexistent"),
    Case("run --backend sim --record {d}/corrupt.db --duration 0.1", protect=("corrupt.db",)),
    Case("run --backend sim --record {d}/img.png --duration 0.1", protect=("img.png",)),
    Case("run --backend sim --record {d}/adir --duration 0.1"),
    # The study store makes its folders (StudyStore): a missing folder is not bad input here.
    Case("run --backend sim --record {d}/nodir/sub/s.db --duration 0.1", expect_fail=False),
    Case("run --backend sim --record /proc/s.db --duration 0.1"),
    Case("run --backend sim --record {d}/bench.csv --duration 0.1", protect=("bench.csv",)),
    Case("run --backend sim --condition support_50 --support 0.25"),
    Case("run --backend sim --condition nonsense"),
    Case("run --backend sim --speed V9"),
    Case("run --backend sim --define-speed V4=abc"),
    Case("run --backend sim --define-speed V4=5000"),
    Case("run --backend sim --define-condition x=2"),
    Case("run --backend sim --height -1"),
    Case("run --backend sim --height nan"),
    Case("run --backend sim --mass 0"),
    Case("run --backend sim --hand-load -2"),
    Case("run --backend sim --lead-in -1"),
    Case("run --backend sim --lead-in nan"),
    Case("run --backend sim --serve"),
    Case("run --backend sim --port 70000 --serve --record {d}/s.db"),
    Case("run --backend sim --lsl-wait 5"),
    Case("run --backend sim --trigger bogus"),
    Case("run --backend sim --imu-max-age-ms 0"),
    Case("run --backend sim --motor-silence-ms nan"),
    Case("run --backend sim --host-stall-ms -5"),
    Case("run --backend sim --slack-timeout -1"),
    Case("run --backend sim --rt-priority 200"),
    Case("run --backend sim --cpu -1"),
    Case("run --backend sim --cpu 4096"),
    Case("run --backend sim --calibration-s nan"),
    Case("run --backend sim --load-cell-gain 0"),
    Case("run --backend sim --motor-id -3"),
    Case("run --backend sim --imu-port -1"),
    Case("run --backend sim --imu lsl:"),
    Case("run --backend sim --imu bogus"),
    Case("run --backend sim --imu-sender not-an-ip"),
    Case("run --backend sim --participant ''"),
    # serve (refusals before it listens only)
    Case("serve --store {d}/corrupt.db", protect=("corrupt.db",)),
    Case("serve --store {d}/img.png", protect=("img.png",)),
    Case("serve --store {d}/adir"),
    Case("serve --store {d}/nodir/sub/s.db"),
    Case("serve --store {d}/foreign.db --port 70000"),
    Case("serve --store {d}/foreign.db --port -1"),
    Case("serve --store {d}/foreign.db --rate-hz 0"),
    Case("serve --store {d}/foreign.db --time-scale 0"),
    Case("serve --store {d}/foreign.db --time-scale nan"),
    Case("serve --store {d}/foreign.db --repetitions 0"),
    Case("serve --store {d}/foreign.db --break-min -1"),
    Case("serve --store {d}/foreign.db --lead-in nan"),
    Case("serve --store {d}/foreign.db --friction-k 2"),
    Case("serve --store {d}/foreign.db --friction-k nan"),
    Case("serve --store {d}/foreign.db --conditions nonsense"),
    Case("serve --store {d}/foreign.db --speeds V9"),
    Case("serve --store {d}/foreign.db --model {d}/img.png"),
    Case("serve --store {d}/foreign.db --model {d}/model_nan.json"),
    Case("serve --store {d}/foreign.db --backend can"),
    # study (bad input only)
    Case("study --participants 0 --out {d}/st"),
    Case("study --participants -3 --out {d}/st"),
    Case("study --participants abc --out {d}/st"),
    Case("study --repetitions 0 --out {d}/st"),
    Case("study --seed -1 --out {d}/st"),
    Case("study --workers 0 --out {d}/st"),
    Case("study --workers -1 --out {d}/st"),
    Case("study --out {d}/existing.txt", protect=("existing.txt",)),
    Case("study --out /proc/st"),
    Case("study --workers 2 --scheduler tcp://127.0.0.1:1 --out {d}/st"),
    # sweep (bad input only)
    Case("sweep nonsense --out {d}/sw"),
    Case("sweep --spec {d}/missing.toml --out {d}/sw"),
    Case("sweep --spec {d}/bad.toml --out {d}/sw"),
    Case("sweep --spec {d}/img.png --out {d}/sw"),
    Case("sweep --spec {d}/adir --out {d}/sw"),
    Case("sweep blend-velocity --participants 0 --out {d}/sw"),
    Case("sweep blend-velocity --repetitions -1 --out {d}/sw"),
    Case("sweep blend-velocity --seeds a,b --out {d}/sw"),
    Case("sweep blend-velocity --seeds -1 --out {d}/sw"),
    Case("sweep blend-velocity --workers 0 --out {d}/sw"),
    Case("sweep blend-velocity --top 0 --out {d}/sw"),
    Case("sweep blend-velocity --axis nonsense=1,2 --out {d}/sw", allow_internal=True),  # lists the axes
    Case("sweep blend-velocity --axis sheath_friction=abc --out {d}/sw"),
    Case("sweep blend-velocity --support 5 --out {d}/sw"),
    Case("sweep blend-velocity --speeds V9 --out {d}/sw"),
    Case("sweep blend-velocity --out {d}/existing.txt", protect=("existing.txt",)),
    Case("sweep blend-velocity --out /proc/sw"),
    Case("sweep"),
    # version
    Case("version --bogus"),
    # bench simulate
    Case("bench simulate -o {d}/nodir/sub/b.csv"),
    Case("bench simulate -o {d}/adir"),
    Case("bench simulate -o /proc/b.csv"),
    Case("bench simulate -o {d}/b.txt"),
    Case("bench simulate -o {d}/existing.txt", protect=("existing.txt",)),
    Case("bench simulate -o {d}/b.csv --speeds 0"),
    Case("bench simulate -o {d}/b.csv --speeds -1"),
    Case("bench simulate -o {d}/b.csv --speeds nan"),
    Case("bench simulate -o {d}/b.csv --loads -1"),
    Case("bench simulate -o {d}/b.csv --repetitions 0"),
    Case("bench simulate -o {d}/b.csv --seed -1"),
    Case("bench simulate -o {d}/b.csv --low-deg 110 --high-deg 20"),
    Case("bench simulate -o {d}/b.csv --high-deg 500"),
    Case("bench simulate -o {d}/b.csv --latency-out {d}/b.csv"),
    Case("bench simulate -o {d}/b.csv --latency-out {d}/nodir/sub/l.csv"),
    # bench run (refusals before any bus; --backend can must fail to open one, in one line)
    Case("bench run -o {d}/br.csv --backend can --channel vcan_nonexistent"),
    Case("bench run -o {d}/bench.csv --backend sim", protect=("bench.csv",)),
    Case("bench run -o {d}/nodir/sub/br.csv --backend sim"),
    Case("bench run -o {d}/nodir/br.csv --backend sim", says="nodir does not exist"),
    Case("bench run -o {d}/existing.txt/br.csv --backend sim", says="existing.txt is not a directory"),
    Case("bench run -o {d}/adir --backend sim"),
    Case("bench run -o {d}/br.csv --backend sim --speeds 0"),
    Case("bench run -o {d}/br.csv --backend sim --loads nan"),
    Case("bench run -o {d}/br.csv --backend sim --repetitions 0"),
    Case("bench run -o {d}/br.csv --backend sim --kp -1"),
    Case("bench run -o {d}/br.csv --backend sim --max-tension 0"),
    Case("bench run -o {d}/br.csv --backend sim --pretension -1"),
    Case("bench run -o {d}/br.csv --backend sim --spool-radius 0"),
    Case("bench run -o {d}/br.csv --backend sim --chirp-s -1"),
    Case("bench run -o {d}/br.csv --backend sim --study-supports 5"),
    Case("bench run -o {d}/br.csv --backend sim --study-repetitions 0"),
    Case("bench run -o {d}/br.csv --backend sim --low-deg 110 --high-deg 20"),
    Case("bench run -o {d}/br.csv --backend sim --mannequin-motor XYZ"),
    Case("bench run -o {d}/img.png --backend sim --resume", protect=("img.png",)),
    Case("bench run -o {d}/other.csv --backend sim --resume", protect=("other.csv",)),
    # bench validate (batch sim only with bad input)
    Case("bench validate {d}/missing.json"),
    Case("bench validate {d}/adir"),
    Case("bench validate {d}/empty.json"),
    Case("bench validate {d}/img.png"),
    Case("bench validate {d}/model_missing.json"),
    Case("bench validate {d}/model_nan.json"),
    Case("bench validate {d}/model_negative.json"),
    Case("bench validate {d}/model.json --support 5"),
    Case("bench validate {d}/model.json --support nan"),
    Case("bench validate {d}/model.json --seed -1 --support 0.5 --study-repetitions 0"),
    Case("bench validate {d}/model.json --recording {d}/img.png"),
    Case("bench validate {d}/model.json --recording {d}/other.csv"),
    Case("bench validate {d}/model.json --recording {d}/missing.csv"),
    Case("bench validate {d}/model.json -o {d}/nodir/sub/m.json"),
    Case("bench validate {d}/model.json --backend sim-wire --bench-output {d}/nodir/v.csv",
         says="(--bench-output) to {d}/nodir/v.csv: the folder {d}/nodir does not exist"),
    Case("bench validate {d}/model.json -o {d}/bench.csv", protect=("bench.csv",)),
    Case("bench validate {d}/model.json --backend sim-wire --bench-output {d}/bench.csv",
         protect=("bench.csv",)),
    Case("bench validate {d}/model.json --backend can --channel vcan_nonexistent"),
]


def _digest(path: Path) -> str | None:
    """The file's bytes, or a bowden store's content: SQLite bumps its header's change counter on a
    write transaction that changed nothing (a store opened and its schema made sure of)."""
    if not path.is_file():
        return None
    if path.name == "store.db":
        with sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True) as conn:
            dump = "\n".join(conn.iterdump())
        conn.close()
        return hashlib.sha256(dump.encode()).hexdigest()
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _message_lines(stderr: str) -> list[str]:
    """Stderr without argparse's usage block (its ``error:`` line is the message)."""
    lines = [line for line in stderr.splitlines() if line.strip()]
    kept, in_usage = [], False
    for line in lines:
        if line.startswith("usage: "):
            in_usage = True
            continue
        if in_usage and line.startswith(" "):
            continue
        in_usage = False
        kept.append(line)
    return kept


def run_case(case: Case, d: Path) -> tuple[int | None, str]:
    """Run one case; fill ``case.flags`` with what breaks the rule; return (exit code, stderr)."""
    import shlex

    argv = [str(BOWDEN), *shlex.split(case.argv.format(d=d))]
    before = {name: _digest(d / name) for name in case.protect}
    try:
        done = subprocess.run(argv, capture_output=True, text=True, timeout=TIMEOUT_S, cwd=d,
                              stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired as expired:
        stderr = expired.stderr.decode() if isinstance(expired.stderr, bytes) else (expired.stderr or "")
        case.flags.append("still running after the timeout (accepted the input?)")
        return None, stderr
    stderr = done.stderr
    if "Traceback (most recent call last)" in stderr:
        case.flags.append("traceback")
    lines = _message_lines(stderr)
    if case.expect_fail and done.returncode == 0:
        case.flags.append("exit 0 on bad input")
    if case.argv.startswith("check") and not lines:
        # bowden check reports on stdout, one line per check: a refusal there is its FAIL lines.
        lines = [line for line in done.stdout.splitlines() if line.startswith("FAIL")]
        if done.returncode != 0 and not lines:
            case.flags.append("exit code 1 without a FAIL line")
    elif done.returncode != 0 and len(lines) != 1:
        case.flags.append(f"{len(lines)} lines on stderr")
    text = " ".join(lines)
    says = case.says.format(d=d)
    if says and says not in text:
        case.flags.append(f"does not say {says!r}")
    words = {m.group(0) for m in INTERNAL_NAME.finditer(text)} | set(BARE_FIELD.findall(text))
    for word in sorted(words - ALLOWED) if not case.allow_internal else ():
        case.flags.append(f"internal name {word!r}")
    for name, digest in before.items():
        if _digest(d / name) != digest:
            case.flags.append(f"{name} modified or deleted")
    shutil.rmtree(d / "nodir", ignore_errors=True)  # a case that made it must not hide the next's refusal
    return done.returncode, "\n".join(lines) if case.argv.startswith("check") else stderr


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-k", default="", help="run only the cases whose command line contains this")
    parser.add_argument("--show", action="store_true", help="print every case's stderr")
    args = parser.parse_args()
    flagged = 0
    with tempfile.TemporaryDirectory(prefix="bowden-misuse-") as tmp:
        d = Path(tmp)
        make_fixtures(d)
        for case in CASES:
            if args.k not in case.argv:
                continue
            code, stderr = run_case(case, d)
            last = (_message_lines(stderr) or [""])[-1][:200]
            mark = "FLAG" if case.flags else "ok  "
            flagged += bool(case.flags)
            print(f"{mark} [{code}] bowden {case.argv.replace('{d}/', '')}")
            if case.flags or args.show:
                print(f"       {'; '.join(case.flags)}" if case.flags else "", end="\n" if case.flags else "")
                print(f"       > {last}")
                if "traceback" in case.flags:
                    print("       > " + "\n       > ".join(stderr.splitlines()[-4:]))
    print(f"{flagged} case(s) flagged")
    return 1 if flagged else 0


if __name__ == "__main__":
    sys.exit(main())
