"""NGIMU (x-io Technologies) client: OSC over UDP → humeral elevation samples.

The NGIMU streams OSC bundles to the host (port 8000 by default). This client reads two messages
(NGIMU user manual, "OSC messages"):

* ``/quaternion w x y z`` — sensor orientation relative to the earth (North-West-Up);
* ``/sensors gx gy gz ax ay az mx my mz baro`` — gyroscope in °/s (sensor frame), then accelerometer
  (g), magnetometer (µT) and barometer (hPa), which are not needed here.

There is no receive thread: :meth:`NgimuClient.read` (the control loop calls it every cycle) takes
in the datagrams waiting on the socket, non-blocking and bounded, parses them with python-osc and
returns the newest sample. Each sample is time-stamped with the injected clock when it is taken in,
so its age is its age at the moment the loop could read it: a stall of the host does not age the IMU,
and no thread competes with the loop for the interpreter. After a stall only the newest datagrams are
parsed (older ones describe an arm that has moved on). The dispatcher uses ``strict_timing=False``:
NGIMU bundles carry the sensor's own time tag, which is not synchronised to the host; with strict
timing, python-osc sleeps until tags "in the future" and the stream stalls.

Only the IMU is listened to: the socket binds ``host`` (loopback by default; the suit's interface on
the real suit), and datagrams are taken only from the configured ``sender`` or, without one, from
the first source whose datagram is OSC, locked in from then on. Anything else is counted as foreign
and never parsed.

Each ``/quaternion`` makes one :class:`~bowden.hardware.ElevationSample` (see
:mod:`bowden.hardware.elevation`). Velocity comes from the latest gyro reading if it is
fresh, else from a filtered difference. Anything that does not parse — random bytes, a bundle cut
short, a message with the wrong arguments — is counted in :class:`NgimuCounters` and dropped; a
non-finite orientation yields a NaN sample, which the loop's watchdog turns into a safe stop.
"""

from __future__ import annotations

import ipaddress
import logging
import math
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Self

from pythonosc import osc_packet
from pythonosc.dispatcher import Dispatcher

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
_MAX_DATAGRAM = 65536


def parse_sender(text: str, field_name: str = "sender") -> tuple[str, int | None]:
    """``"IP"`` or ``"IP:port"`` → (ip, port or None).

    Raises
    ------
    ParameterError
        Naming ``field_name`` when the text is not an IP address, optionally with a port.
    """
    host, _, port_text = text.rpartition(":") if text.count(":") == 1 else (text, "", "")
    try:
        ipaddress.ip_address(host)
        port = int(port_text) if port_text else None
    except ValueError:
        raise ParameterError(f"NgimuConfig.{field_name} must be an IP address, optionally with :port, "
                             f"got {text!r}") from None
    if port is not None and not 1 <= port <= 65535:
        raise ParameterError(f"NgimuConfig.{field_name} port must be 1–65535, got {port}")
    return host, port


@dataclass(frozen=True, kw_only=True)
class NgimuConfig:
    """Where to listen and how to turn orientation into elevation.

    Parameters
    ----------
    host, port
        Address to bind: loopback by default (the simulated suit); on the real suit the address of
        the interface the IMU sends to (``0.0.0.0``: every interface). Port 0: any free port, see
        :attr:`NgimuClient.address`.
    sender
        Accept datagrams only from this source, ``"IP"`` or ``"IP:port"``; None: from the first
        source that sends OSC, locked in from then on (logged).
    max_datagrams_per_read
        Datagrams taken from the socket per :meth:`NgimuClient.read` at most (a flood cannot hold the
        loop; the rest waits for the next call).
    parse_newest
        Of the datagrams taken in one read, only this many newest are parsed (after a stall, the
        older ones describe an arm that has moved on).
    gyro_max_age_s
        A gyro reading older than this (s, on the client clock) is not used for velocity.
    min_elevation_for_gyro_rad
        Below this elevation the gyro axis is ill-defined; velocity comes from the difference.
    velocity_cutoff_hz
        Corner frequency of the difference-velocity low-pass.
    """

    host: str = "127.0.0.1"
    port: int = DEFAULT_HOST_PORT
    sender: str | None = None
    max_datagrams_per_read: int = 256
    parse_newest: int = 16
    gyro_max_age_s: float = 0.02
    min_elevation_for_gyro_rad: float = math.radians(5.0)
    velocity_cutoff_hz: float = 20.0

    def __post_init__(self) -> None:
        try:
            ipaddress.ip_address(self.host)
        except ValueError:
            raise ParameterError(f"NgimuConfig.host must be an IP address to bind, got {self.host!r}")\
                from None
        if self.sender is not None:
            parse_sender(self.sender)
        for name in ("max_datagrams_per_read", "parse_newest"):
            if getattr(self, name) < 1:
                raise ParameterError(f"NgimuConfig.{name} must be >= 1, got {getattr(self, name)}")
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
    foreign: int = 0  # datagrams from a source other than the IMU, dropped unparsed
    skipped_backlog: int = 0  # older datagrams of a read not parsed (after a stall)
    read_limit_hits: int = 0  # reads that left datagrams on the socket
    quaternions: int = 0
    gyro_readings: int = 0
    non_finite: int = 0


def _is_osc(data: bytes) -> bool:
    """True if ``data`` parses as an OSC message or bundle."""
    try:
        osc_packet.OscPacket(data)
    except Exception:  # untrusted bytes: any parser failure means not OSC
        return False
    return True


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
        self._socket: socket.socket | None = None
        self._lock = threading.Lock()  # one reader of the socket at a time (loop, console, calibration)
        self._allowed: tuple[str, int | None] | None = (
            parse_sender(self.config.sender) if self.config.sender is not None else None
        )
        self._foreign_seen: set[tuple[str, int]] = set()

    # --- lifecycle -------------------------------------------------------------------------------
    def start(self) -> Self:
        """Bind the UDP port (non-blocking; datagrams are taken in by :meth:`read`)."""
        if self._socket is None:
            family = socket.AF_INET6 if ":" in self.config.host else socket.AF_INET
            sock = socket.socket(family, socket.SOCK_DGRAM)
            try:
                sock.bind((self.config.host, self.config.port))
            except OSError:
                sock.close()
                raise
            sock.setblocking(False)
            self._socket = sock
        return self

    def close(self) -> None:
        """Close the socket."""
        with self._lock:
            if self._socket is not None:
                self._socket.close()
                self._socket = None

    @property
    def address(self) -> tuple[str, int]:
        """The bound (host, port); useful with port 0."""
        if self._socket is None:
            raise ParameterError("NgimuClient is not started")
        host, port = self._socket.getsockname()[:2]
        return str(host), int(port)

    @property
    def sender(self) -> tuple[str, int | None] | None:
        """The source accepted (configured, or locked on the first OSC datagram), None until then."""
        return self._allowed

    # --- ElevationSensor -------------------------------------------------------------------------
    def read(self) -> ElevationSample | None:
        """Take in what arrived (non-blocking, bounded) and return the latest elevation sample, or
        None before calibration or the first message."""
        self.poll()
        return self._latest

    def poll(self) -> int:
        """Take in the datagrams waiting on the socket (bounded); return how many were taken."""
        with self._lock:
            sock = self._socket
            if sock is None:
                return 0
            received: list[tuple[bytes, tuple[str, int]]] = []
            limit = self.config.max_datagrams_per_read
            for _ in range(limit):
                try:
                    data, source = sock.recvfrom(_MAX_DATAGRAM)
                except (BlockingIOError, InterruptedError):
                    break
                except OSError:  # e.g. an ICMP error queued on the socket: not a datagram
                    continue
                received.append((data, (str(source[0]), int(source[1]))))
            else:
                self.counters.read_limit_hits += 1
            newest = self.config.parse_newest
            if len(received) > newest:
                self.counters.skipped_backlog += len(received) - newest
                self.counters.datagrams += len(received) - newest
                received = received[-newest:]
            for data, source in received:
                self._take(data, source)
            return len(received)

    def calibrate_arm_down(self, duration_s: float = 1.0, *, min_samples: int = 10) -> ArmDownCalibration:
        """Average the orientation while the arm hangs still for ``duration_s`` and use it.

        Raises
        ------
        DeviceTimeoutError
            If fewer than ``min_samples`` orientations arrived (IMU not streaming to this host?).
        """
        self.poll()  # what was sent before the call describes the arm before the pose: not collected
        self._collecting = []
        end = time.monotonic() + duration_s
        while time.monotonic() < end:
            self.poll()
            time.sleep(0.002)
        self.poll()
        collected, self._collecting = self._collecting, None
        if len(collected) < min_samples:
            raise DeviceTimeoutError(
                f"NGIMU calibration got {len(collected)} orientations in {duration_s} s "
                f"(need {min_samples}): is the IMU sending /quaternion to port {self.config.port}?"
            )
        self.calibration = ArmDownCalibration.from_quaternions(collected)
        _log.info("NGIMU arm-down calibration: humeral axis %s", self.calibration.axis)
        return self.calibration

    def handle_datagram(self, data: bytes, sender: tuple[str, int] = ("127.0.0.1", 0)) -> None:
        """Process one UDP payload as if it had arrived from ``sender`` (:meth:`read` takes the same
        path)."""
        with self._lock:
            self._take(data, sender)

    def _take(self, data: bytes, source: tuple[str, int]) -> None:
        allowed = self._allowed
        if allowed is None:
            if not _is_osc(data):
                self.counters.datagrams += 1
                self.counters.malformed += 1
                return
            self._allowed = allowed = (source[0], source[1])
            _log.info("NGIMU: accepting only %s:%d from now on", source[0], source[1])
        if source[0] != allowed[0] or (allowed[1] is not None and source[1] != allowed[1]):
            self.counters.foreign += 1
            if source not in self._foreign_seen:
                self._foreign_seen.add(source)
                _log.warning("NGIMU: ignoring datagrams from %s:%d (not the IMU %s)", source[0], source[1],
                             allowed[0] if allowed[1] is None else f"{allowed[0]}:{allowed[1]}")
            return
        self._dispatcher.call_handlers_for_packet(data, source)

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
