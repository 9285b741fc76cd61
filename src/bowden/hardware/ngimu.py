"""NGIMU (x-io Technologies) client: OSC over UDP → humeral elevation samples.

The NGIMU streams OSC bundles to the host (port 8000 by default). This client reads two messages
(NGIMU user manual, "OSC messages"):

* ``/quaternion w x y z`` — sensor orientation relative to the earth (North-West-Up);
* ``/sensors gx gy gz ax ay az mx my mz baro`` — gyroscope in °/s (sensor frame), then accelerometer
  (g), magnetometer (µT) and barometer (hPa), which are not needed here.

A python-osc server runs in one background thread (a thread per datagram would cost more than the
work it does at 100–400 messages/s and could reorder samples). The dispatcher uses
``strict_timing=False``: NGIMU bundles carry the sensor's own time tag, which is not synchronised to
the host; with strict timing, python-osc sleeps until tags "in the future" and the stream stalls.

Each ``/quaternion`` makes one :class:`~bowden.hardware.ElevationSample` (see
:mod:`bowden.hardware.elevation`), time-stamped with the injected clock on arrival, so the loop's
staleness watchdog compares like with like. Velocity comes from the latest gyro reading if it is
fresh, else from a filtered difference. Anything that does not parse — random bytes, a bundle cut
short, a message with the wrong arguments — is counted in :class:`NgimuCounters` and dropped; a
non-finite orientation yields a NaN sample, which the loop's watchdog turns into a safe stop.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Self

from pythonosc import osc_packet
from pythonosc.dispatcher import Dispatcher
from pythonosc.osc_server import BlockingOSCUDPServer

from bowden.errors import DeviceTimeoutError, ParameterError
from bowden.hardware.elevation import (
    ArmDownCalibration,
    DifferenceVelocity,
    elevation_from_direction,
    elevation_velocity_from_gyro,
    humerus_direction,
    quaternion_normalised,
)
from bowden.hardware.lifecycle import StartedInWith
from bowden.hardware.protocols import ElevationSample

_log = logging.getLogger(__name__)
QUATERNION_ADDRESS = "/quaternion"
SENSORS_ADDRESS = "/sensors"
DEFAULT_HOST_PORT = 8000


@dataclass(frozen=True, kw_only=True)
class NgimuConfig:
    """Where to listen and how to turn orientation into elevation.

    Parameters
    ----------
    host, port
        Address to bind (port 0: any free port, see :attr:`NgimuClient.address`).
    gyro_max_age_s
        A gyro reading older than this (s, on the client clock) is not used for velocity.
    min_elevation_for_gyro_rad
        Below this elevation the gyro axis is ill-defined; velocity comes from the difference.
    velocity_cutoff_hz
        Corner frequency of the difference-velocity low-pass.
    """

    host: str = "0.0.0.0"
    port: int = DEFAULT_HOST_PORT
    gyro_max_age_s: float = 0.02
    min_elevation_for_gyro_rad: float = math.radians(5.0)
    velocity_cutoff_hz: float = 20.0

    def __post_init__(self) -> None:
        if not 0 <= self.port <= 65535:
            raise ParameterError(f"NgimuConfig.port must be 0..65535, got {self.port}")
        if not (math.isfinite(self.gyro_max_age_s) and self.gyro_max_age_s > 0.0):
            raise ParameterError(f"NgimuConfig.gyro_max_age_s must be positive, got {self.gyro_max_age_s}")
        if not 0.0 < self.min_elevation_for_gyro_rad < math.pi / 2:
            raise ParameterError("NgimuConfig.min_elevation_for_gyro_rad must be in (0, π/2)")
        if not (math.isfinite(self.velocity_cutoff_hz) and self.velocity_cutoff_hz > 0.0):
            raise ParameterError(
                f"NgimuConfig.velocity_cutoff_hz must be positive, got {self.velocity_cutoff_hz}"
            )


@dataclass
class NgimuCounters:
    """Datagrams and messages seen, and why some were dropped."""

    datagrams: int = 0
    malformed: int = 0  # not OSC at all, or a packet that does not parse
    bad_messages: int = 0  # a known address with the wrong arguments
    unknown_addresses: int = 0
    quaternions: int = 0
    gyro_readings: int = 0
    non_finite: int = 0


def _floats(params: list[Any], count: int) -> tuple[float, ...] | None:
    """The first ``count`` OSC arguments as floats, or None if they are not numbers."""
    if len(params) < count:
        return None
    values = params[:count]
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
        return None
    return tuple(float(v) for v in values)


class _CountingDispatcher(Dispatcher):
    """python-osc's dispatcher, but parse failures are counted instead of silently passed over."""

    def __init__(self, counters: NgimuCounters) -> None:
        super().__init__(strict_timing=False)
        self._counters = counters

    def call_handlers_for_packet(self, data: bytes, client_address: tuple[str, int]) -> list[Any]:
        self._counters.datagrams += 1
        try:
            messages = osc_packet.OscPacket(data).messages
        except Exception:  # untrusted bytes: any parser failure is a malformed datagram, never a crash
            self._counters.malformed += 1
            return []
        for timed in messages:
            handlers = list(self.handlers_for_address(timed.message.address))
            for handler in handlers:
                handler.invoke(client_address, timed.message)
        return []


class _CountingServer(BlockingOSCUDPServer):
    """Counts datagrams python-osc rejects before dispatch (not starting with ``/`` or ``#bundle``)."""

    def __init__(self, address: tuple[str, int], dispatcher: _CountingDispatcher, counters: NgimuCounters):
        self._counters = counters
        super().__init__(address, dispatcher)

    def verify_request(self, request: Any, client_address: Any) -> bool:
        accepted = bool(super().verify_request(request, client_address))
        if not accepted:
            self._counters.datagrams += 1
            self._counters.malformed += 1
        return accepted


class NgimuClient(StartedInWith):
    """Elevation from an NGIMU on the upper arm (implements :class:`~bowden.hardware.ElevationSensor`).

    Parameters
    ----------
    config
        :class:`NgimuConfig`.
    calibration
        The humeral axis from an earlier arm-down calibration, or None to calibrate with
        :meth:`calibrate_arm_down` (``read`` returns None until then).
    clock
        Monotonic clock (s) stamping each sample on arrival; the loop's clock.
    """

    def __init__(
        self,
        config: NgimuConfig | None = None,
        *,
        calibration: ArmDownCalibration | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.config = config if config is not None else NgimuConfig()
        self.calibration = calibration
        self._clock = clock
        self.counters = NgimuCounters()
        self._dispatcher = _CountingDispatcher(self.counters)
        self._dispatcher.map(QUATERNION_ADDRESS, self._on_quaternion)
        self._dispatcher.map(SENSORS_ADDRESS, self._on_sensors)
        self._dispatcher.set_default_handler(self._on_unknown)
        self._difference = DifferenceVelocity(self.config.velocity_cutoff_hz)
        self._min_sin = math.sin(self.config.min_elevation_for_gyro_rad)
        self._gyro_rad_s: tuple[float, float, float] = (math.nan, math.nan, math.nan)
        self._gyro_time_s = -math.inf
        self._latest: ElevationSample | None = None
        self._latest_quaternion: tuple[float, float, float, float] | None = None
        self._collecting: list[tuple[float, float, float, float]] | None = None
        self._server: _CountingServer | None = None
        self._thread: threading.Thread | None = None

    # --- lifecycle -------------------------------------------------------------------------------
    def start(self) -> Self:
        """Bind the UDP port and start receiving in a background thread."""
        if self._server is None:
            address = (self.config.host, self.config.port)
            self._server = _CountingServer(address, self._dispatcher, self.counters)
            self._thread = threading.Thread(
                target=self._server.serve_forever, kwargs={"poll_interval": 0.05},
                name="ngimu-osc", daemon=True,
            )
            self._thread.start()
        return self

    def close(self) -> None:
        """Stop the server thread and close the socket."""
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
            self._server = None
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None

    @property
    def address(self) -> tuple[str, int]:
        """The bound (host, port); useful with port 0."""
        if self._server is None:
            raise ParameterError("NgimuClient is not started")
        host, port = self._server.server_address[:2]
        return str(host), int(port)

    # --- ElevationSensor -------------------------------------------------------------------------
    def read(self) -> ElevationSample | None:
        """The latest elevation sample, or None before calibration or the first message."""
        return self._latest

    def calibrate_arm_down(self, duration_s: float = 1.0, *, min_samples: int = 10) -> ArmDownCalibration:
        """Average the orientation while the arm hangs still for ``duration_s`` and use it.

        Raises
        ------
        DeviceTimeoutError
            If fewer than ``min_samples`` orientations arrived (IMU not streaming to this host?).
        """
        self._collecting = []
        time.sleep(duration_s)
        collected, self._collecting = self._collecting, None
        if len(collected) < min_samples:
            raise DeviceTimeoutError(
                f"NGIMU calibration got {len(collected)} orientations in {duration_s} s "
                f"(need {min_samples}): is the IMU sending /quaternion to port {self.config.port}?"
            )
        self.calibration = ArmDownCalibration.from_quaternions(collected)
        _log.info("NGIMU arm-down calibration: humeral axis %s", self.calibration.axis)
        return self.calibration

    def handle_datagram(self, data: bytes) -> None:
        """Process one UDP payload as if it had arrived (the receive thread calls the same path)."""
        self._dispatcher.call_handlers_for_packet(data, ("", 0))

    # --- handlers (receive thread) ----------------------------------------------------------------
    def _on_unknown(self, address: str, *params: Any) -> None:
        self.counters.unknown_addresses += 1

    def _on_sensors(self, address: str, *params: Any) -> None:
        values = _floats(list(params), 3)
        if values is None:
            self.counters.bad_messages += 1
            return
        self.counters.gyro_readings += 1
        deg = math.pi / 180.0
        self._gyro_rad_s = (values[0] * deg, values[1] * deg, values[2] * deg)
        self._gyro_time_s = self._clock()

    def _on_quaternion(self, address: str, *params: Any) -> None:
        values = _floats(list(params), 4)
        if values is None:
            self.counters.bad_messages += 1
            return
        self.counters.quaternions += 1
        q = quaternion_normalised(values)
        now = self._clock()
        if math.isnan(q[0]):
            self.counters.non_finite += 1
        collecting = self._collecting
        if collecting is not None:
            collecting.append(q)
        calibration = self.calibration
        if calibration is None:
            return
        u = humerus_direction(q, calibration)
        elevation = elevation_from_direction(u)
        fallback = self._difference.update(now, elevation)
        velocity = math.nan
        if now - self._gyro_time_s <= self.config.gyro_max_age_s:
            velocity = elevation_velocity_from_gyro(q, u, self._gyro_rad_s, self._min_sin)
        if math.isnan(velocity):
            velocity = fallback if math.isfinite(elevation) else math.nan
        self._latest = ElevationSample(now, elevation, velocity)
