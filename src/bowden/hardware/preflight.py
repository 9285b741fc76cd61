"""The pre-flight checks of ``bowden check``: each device, before the participant arrives.

Each function checks one thing and returns a :class:`Check` — ok, or what is wrong and what to do —
and never raises for what it finds (a device's fault is a failed check, not an exception), so one
broken device does not hide the state of the others. The command (:mod:`bowden.cli.check`) opens
the devices, real or simulated, and calls these on them; the console shows the same list.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from bowden.errors import BowdenError
from bowden.hardware.ak60_codec import MotorErrorCode
from bowden.hardware.motors import AKMotorModel
from bowden.hardware.protocols import ElevationSensor, TensionSensor

if TYPE_CHECKING:  # the driver imports python-can: `bowden --help` lists `check` without it
    from bowden.hardware.ak60 import AK60Motor

CAN_BITRATE: Final = 1_000_000  # every AK model (CubeMars driver manual V1.0.8 §5.3: "CAN Speed: 1 MHZ")
TEMPERATURE_MARGIN_C: Final = 10.0  # below the loop's over-temperature stop (80 °C): room for a session
REST_ELEVATION_MAX_DEG: Final = 15.0  # the arm hangs: far below any raise of the protocol (20°–100°)
REST_VELOCITY_MAX_DEG_S: Final = 20.0
LOAD_CELL_ZERO_N: Final = 5.0  # the slack take-up's pretension: a zero off by more would read as taut
RATE_FRACTION: Final = 0.8  # an IMU sending less than this share of its expected rate is misconfigured
# Upper bound of the store's size per row: ~30 columns of 8 bytes, uncompressed (the store compresses
# its sample blocks; docs/design.md "File format of the study store"), doubled for the WAL.
BYTES_PER_ROW: Final = 2 * 30 * 8


@dataclass(frozen=True, slots=True)
class Check:
    """One line of the pre-flight: ``name`` (``can``, ``motor``, ``imu``, ...), ok, and the message."""

    name: str
    ok: bool
    message: str

    def line(self) -> str:
        return f"{'ok  ' if self.ok else 'FAIL'} {self.name}: {self.message}"

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True, slots=True)
class LinkState:
    """What the OS says about a CAN interface: whether it exists, is up, and its bitrate (None: unknown)."""

    exists: bool
    up: bool
    bitrate: int | None = None
    can_state: str | None = None  # the controller's: ERROR-ACTIVE, ERROR-WARNING, BUS-OFF, STOPPED...


def socketcan_link(channel: str, run: Callable[..., Any] = subprocess.run) -> LinkState:
    """The state of ``channel`` from ``ip -details -json link show`` (iproute2), else from sysfs."""
    try:
        result = run(["ip", "-details", "-json", "link", "show", channel], capture_output=True, text=True,
                     timeout=5.0, check=False)
    except (OSError, subprocess.TimeoutExpired):
        result = None
    if result is not None and result.returncode == 0:
        try:
            link = json.loads(result.stdout)[0]
            flags = link.get("flags", [])
            data = link.get("linkinfo", {}).get("info_data", {})
            bitrate = data.get("bittiming", {}).get("bitrate")
            return LinkState(exists=True, up="UP" in flags,
                             bitrate=int(bitrate) if bitrate is not None else None,
                             can_state=data.get("state"))
        except (ValueError, IndexError, KeyError, TypeError, AttributeError):
            pass
    base = Path("/sys/class/net") / channel
    if not base.exists():
        return LinkState(exists=False, up=False)
    try:
        flags_value = int((base / "flags").read_text().strip(), 16)
    except (OSError, ValueError):
        return LinkState(exists=True, up=False)
    return LinkState(exists=True, up=bool(flags_value & 0x1))  # IFF_UP


def check_can_link(channel: str, state: LinkState, bitrate: int = CAN_BITRATE) -> Check:
    """The CAN interface exists, is up, and runs at ``bitrate``."""
    setup = f"sudo ip link set {channel} up type can bitrate {bitrate} restart-ms 100"
    if not state.exists:
        return Check("can", False, f"no CAN interface {channel}: enable the CAN overlay or driver, then "
                     f"{setup} (docs/hardware.md §1; --channel names another)")
    if not state.up:
        return Check("can", False, f"the CAN interface {channel} is down: {setup}")
    if state.bitrate is not None and state.bitrate != bitrate:
        return Check("can", False, f"{channel} runs at {state.bitrate} bit/s, the AK motors at {bitrate}: "
                     f"sudo ip link set {channel} down, then {setup}")
    if state.can_state in ("BUS-OFF", "STOPPED"):
        return Check("can", False, f"{channel} is {state.can_state}: nothing acknowledges its frames (motor "
                     f"unpowered? 120 Ω at each end?); then sudo ip link set {channel} down, and {setup}")
    rate = "bitrate not reported" if state.bitrate is None else f"{state.bitrate} bit/s"
    return Check("can", True, f"{channel} up, {rate}")


def check_motor(motor: AK60Motor, model: AKMotorModel, firmware: str | None, *,
                max_temperature_c: float = 80.0) -> Check:
    """Enter motor mode (no torque is commanded), read one reply, leave motor mode.

    The reply says the motor answers on its id; its length says the firmware generation (6 bytes:
    older, no temperature); its temperature must leave room below the loop's stop, its error code
    must be none. The field ranges themselves do not show at rest: they are the ``--motor`` and
    ``--firmware`` named (docs/hardware.md §1 item 5 says how to verify them with a weight).
    """
    config = motor.config
    name = f"{model.name} id {config.motor_id}"
    try:
        state = motor.enable()
    except BowdenError as error:
        hint = ("frames came but none was this motor's reply: another --motor-id, or V3 firmware "
                "(extended ids)" if motor.counters.foreign else "no frame at all: power, wiring, "
                "termination, --motor-id")
        return Check("motor", False, f"{name} does not answer ({error}); {hint}")
    finally:
        motor.disable()
    ranges = f"{firmware or model.default_firmware} ranges {model.describe_limits(firmware)}"
    if state.error_code != 0:
        return Check("motor", False, f"{name} reports {MotorErrorCode.describe(state.error_code)} "
                     f"(error code {state.error_code}): power-cycle it and check supply and wiring")
    if math.isnan(state.temperature_c):
        return Check("motor", True, f"{name} answers (6-byte replies: older firmware, no temperature); "
                     f"{ranges}")
    limit = max_temperature_c - TEMPERATURE_MARGIN_C
    if state.temperature_c >= limit:
        return Check("motor", False, f"{name} is at {state.temperature_c:.0f} °C, within "
                     f"{TEMPERATURE_MARGIN_C:g} °C of the {max_temperature_c:g} °C stop: let it cool")
    return Check("motor", True, f"{name} answers, {state.temperature_c:.0f} °C, {ranges}")


def check_imu_stream(imu: ElevationSensor, received: Callable[[], int], *, expected_rate_hz: float,
                     window_s: float = 0.5, sleep: Callable[[float], None] = time.sleep,
                     clock: Callable[[], float] = time.monotonic) -> Check:
    """The calibrated IMU streams at ``expected_rate_hz`` and its elevation is plausible at rest.

    ``received`` counts the orientations taken in so far (the driver's counter); the window is
    measured, not assumed.
    """
    start_count, start = received(), clock()
    latest = None
    while clock() - start < window_s:
        latest = imu.read() or latest
        sleep(0.002)
    rate_hz = (received() - start_count) / (clock() - start)
    if latest is None or rate_hz == 0.0:
        return Check("imu", False, f"no orientation for {window_s:g} s after the calibration: the IMU "
                     "stopped sending")
    if rate_hz < RATE_FRACTION * expected_rate_hz:
        return Check("imu", False, f"{rate_hz:.0f} orientations/s, expected {expected_rate_hz:g} "
                     "(--imu-rate): raise the IMU's quaternion send rate, or check the Wi-Fi")
    elevation_deg = math.degrees(latest.elevation_rad)
    velocity_deg_s = math.degrees(latest.elevation_velocity_rad_s)
    if not (math.isfinite(elevation_deg) and math.isfinite(velocity_deg_s)):
        return Check("imu", False, "the IMU sends non-finite orientations: restart it")
    if abs(elevation_deg) > REST_ELEVATION_MAX_DEG or abs(velocity_deg_s) > REST_VELOCITY_MAX_DEG_S:
        return Check("imu", False, f"elevation {elevation_deg:.0f}° moving at {velocity_deg_s:.0f}°/s with "
                     "the arm hanging still: is the IMU strapped to the upper arm, and the arm still?")
    return Check("imu", True, f"{rate_hz:.0f} orientations/s, elevation {elevation_deg:.1f}° at rest")


def check_load_cell(load_cell: TensionSensor, *, window_s: float = 0.3,
                    sleep: Callable[[float], None] = time.sleep,
                    clock: Callable[[], float] = time.monotonic) -> Check:
    """The load cell reads, and reads zero with the cable slack (its calibration, no tare)."""
    readings: list[float] = []
    end = clock() + window_s
    while clock() < end:
        sample = load_cell.read()
        if sample is not None:
            readings.append(sample.tension_n)
        sleep(0.005)
    if load_cell.failure is not None or not readings:
        why = load_cell.failure or f"no reading in {window_s:g} s"
        return Check("load_cell", False, f"{why}: check the I²C wiring and --i2c-bus (i2cdetect)")
    mean_n = sum(readings) / len(readings)
    if abs(mean_n) > LOAD_CELL_ZERO_N:
        return Check("load_cell", False, f"reads {mean_n:.1f} N with the cable slack (zero within "
                     f"{LOAD_CELL_ZERO_N:g} N expected): slacken the cable, else zero the amplifier")
    return Check("load_cell", True, f"reads {mean_n:.1f} N with the cable slack")


def check_store(path: Path, *, session_s: float, rate_hz: float,
                disk_usage: Callable[[str], Any] | None = None) -> Check:
    """The store's directory takes a file, and its disk has room for ``session_s`` of rows."""
    directory = path.parent if path.parent != Path("") else Path(".")
    if not directory.is_dir():
        return Check("store", False, f"{directory} does not exist: create it or give another --record")
    try:
        with tempfile.NamedTemporaryFile(dir=directory, prefix=".bowden-check-") as probe:
            probe.write(b"\0" * 4096)
            probe.flush()
            os.fsync(probe.fileno())
    except OSError as error:
        return Check("store", False, f"cannot write in {directory}: {error.strerror or error}")
    need = int(session_s * rate_hz * BYTES_PER_ROW)
    free = int((disk_usage or shutil.disk_usage)(str(directory)).free)
    if free < need:
        return Check("store", False, f"{free / 1e6:.0f} MB free on the disk of {path}, a "
                     f"{session_s / 60:g}-min session at {rate_hz:g} Hz needs up to {need / 1e6:.0f} MB: "
                     "free some space or record elsewhere")
    return Check("store", True, f"{path} writable, {free / 1e9:.1f} GB free "
                 f"(the session needs at most {need / 1e6:.0f} MB)")
