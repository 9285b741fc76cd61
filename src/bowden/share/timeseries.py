"""A trial's control cycles as BIDS tabular time series: the IMU elevation as motion, the loop as physio.

- ``motion/…_tracksys-imu_…_motion.tsv`` (BIDS motion, BEP029: bids-specification
  ``src/modality-specific-files/motion.md``): no header row, one column per row of its
  ``_channels.tsv``: ``LATENCY`` (the loop time of each cycle, s: the loop's cycles are timed, not
  assumed even) and the upper arm's elevation measured by the IMU (``JNTANG``, rad as stored; the spec
  recommends degrees, converting would not be lossless).
- ``beh/…_recording-loop_physio.tsv.gz`` (BIDS physiological recordings, continuous data:
  ``src/modality-specific-files/physiological-recordings.md``): every column of the store's samples
  (``contracts.TRIAL_COLUMNS``: reference and measured elevation, desired tension, moment arm, commanded
  and measured motor torque, motor velocity, load cell tension, loop state and faults) in that order,
  named and described in its ``_physio.json``, with the compensation model the controller used.

Numbers are written as Python's shortest round-trip text (``repr``), so each float64 reads back equal
to the store's; a missing value (no load cell: NaN) is ``n/a``.
"""

from __future__ import annotations

import gzip
from pathlib import Path
from typing import Any, Final

import numpy as np
import pandas as pd

from bowden.contracts import (
    TRIAL_COLUMNS,
    TRIAL_COMMANDED_TORQUE,
    TRIAL_DESIRED_TENSION,
    TRIAL_ELEVATION,
    TRIAL_ELEVATION_VELOCITY,
    TRIAL_FAULT,
    TRIAL_MOMENT_ARM,
    TRIAL_MOTOR_TORQUE,
    TRIAL_MOTOR_VELOCITY,
    TRIAL_REFERENCE_ELEVATION,
    TRIAL_STATE,
    TRIAL_TENSION,
    TRIAL_TIME,
)

# Each stored column: (unit, description), for the physio sidecar.
LOOP_COLUMNS: Final[dict[str, tuple[str, str]]] = {
    TRIAL_TIME: ("s", "loop time of the control cycle"),
    TRIAL_REFERENCE_ELEVATION: ("rad", "elevation the display asked for (the reference)"),
    TRIAL_ELEVATION: ("rad", "upper-arm elevation measured by the IMU"),
    TRIAL_ELEVATION_VELOCITY: ("rad/s", "elevation velocity (IMU)"),
    TRIAL_DESIRED_TENSION: ("N", "cable tension the assistance asked for"),
    TRIAL_MOMENT_ARM: ("m", "moment arm of the cable about the shoulder used this cycle"),
    TRIAL_COMMANDED_TORQUE: ("N.m", "motor torque sent: the desired tension through the compensation model"),
    TRIAL_MOTOR_TORQUE: ("N.m", "motor torque the motor reported"),
    TRIAL_MOTOR_VELOCITY: ("rad/s", "motor velocity the motor reported"),
    TRIAL_TENSION: ("N", "cable tension measured by the load cell (n/a: no load cell)"),
    TRIAL_STATE: ("n/a", "control loop state: 1 running, 2 ramping down, 3 safe (bowden.contracts)"),
    TRIAL_FAULT: ("n/a", "bit set of the loop's faults (bowden.control.Fault)"),
}
assert tuple(LOOP_COLUMNS) == TRIAL_COLUMNS  # every stored column, in the store's order
_INTEGER: Final = frozenset({TRIAL_STATE, TRIAL_FAULT})


def nominal_rate_hz(time_s: np.ndarray[Any, Any]) -> float:
    """The loop's rate from its median cycle (the sidecars' SamplingFrequency)."""
    steps = np.diff(time_s)
    return float(1.0 / np.median(steps)) if steps.size else 0.0


def write_motion(path: Path, samples: pd.DataFrame) -> dict[str, Any]:
    """The motion TSV (latency, elevation); returns its sidecar's rate fields."""
    _write_tsv(path, samples[[TRIAL_TIME, TRIAL_ELEVATION]], compress=False)
    time = samples[TRIAL_TIME].to_numpy(dtype=np.float64)
    effective = (time.size - 1) / (time[-1] - time[0]) if time.size > 1 and time[-1] > time[0] else "n/a"
    return {"SamplingFrequency": nominal_rate_hz(time), "SamplingFrequencyEffective": effective}


MOTION_CHANNELS: Final = pd.DataFrame(
    {
        "name": ["latency", "elevation"],
        "component": ["n/a", "n/a"],
        "type": ["LATENCY", "JNTANG"],
        "tracked_point": ["n/a", "upper_arm"],
        "units": ["s", "rad"],
        "description": [
            "loop time of the control cycle (the file's first row is its first cycle)",
            "humeral elevation: angle of the upper arm from the trunk's vertical, measured by the IMU",
        ],
    }
)


def motion_sidecar(rates: dict[str, Any], *, task: str, simulated: bool) -> dict[str, Any]:
    return {
        "TaskName": task,
        **rates,
        "MotionChannelCount": 2,
        "JNTANGChannelCount": 1,
        "LATENCYChannelCount": 1,
        "TrackedPointsCount": 1,
        "MissingValues": "n/a",
        "TrackingSystemName": "simulated IMU (bowden.sim)" if simulated else "IMU on the upper arm",
    }


def write_physio(path: Path, samples: pd.DataFrame) -> None:
    """The loop's physio file (every stored column, gzip, no header)."""
    _write_tsv(path, samples[list(TRIAL_COLUMNS)], compress=True)


def physio_sidecar(time_s: np.ndarray[Any, Any], *, start_time_s: float, model: Any) -> dict[str, Any]:
    sidecar: dict[str, Any] = {
        "SamplingFrequency": nominal_rate_hz(time_s),
        "StartTime": start_time_s,
        "PhysioType": "generic",
        "Columns": list(TRIAL_COLUMNS),
    }
    for name, (unit, description) in LOOP_COLUMNS.items():
        sidecar[name] = {"Description": description, "Units": unit}
    if model is not None:
        sidecar["CompensationModel"] = model
    return sidecar


def _write_tsv(path: Path, frame: pd.DataFrame, *, compress: bool) -> None:
    """Rows of ``frame`` as tab-separated shortest round-trip text, without a header."""
    columns = []
    for name in frame.columns:
        values = frame[name].to_numpy()
        if name in _INTEGER:
            columns.append([str(int(v)) for v in values])
        else:
            columns.append(["n/a" if v != v else repr(float(v)) for v in values.astype(np.float64)])
    text = "".join("\t".join(row) + "\n" for row in zip(*columns, strict=True))
    if compress:
        # No file name (the validator warns of one) and mtime 0 in the gzip header: one store, one file.
        with path.open("wb") as raw, gzip.GzipFile(filename="", fileobj=raw, mode="wb", mtime=0) as out:
            out.write(text.encode())
    else:
        path.write_text(text)
