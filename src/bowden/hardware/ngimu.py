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
and no thread competes with the loop for the interpreter. After a stall only the newest datagrams of
the IMU are parsed (older ones describe an arm that has moved on). The dispatcher uses
``strict_timing=False``: NGIMU bundles carry the sensor's own time tag, which is not synchronised to
the host; with strict timing, python-osc sleeps until tags "in the future" and the stream stalls.

Only the IMU is listened to: the socket binds ``host`` (loopback by default; the suit's interface on
the real suit), and datagrams are taken only from the configured ``sender`` or, without one, from
the first source whose datagram is OSC, locked in from then on. Anything else is counted as foreign
and never parsed. (This keeps other programs and stray senders out; it is not authentication: on a
shared network a source address can be forged, so the IMU belongs on a network of its own.)

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
_FOREIGN_SOURCES_LOGGED = 32  # distinct foreign sources warned about one by one; then one last warning
_CALIBRATION_POLL_S = 0.002  # sleep between polls of the socket during the arm-down calibration
_MAX_PORT = 65535

SenderAddress = tuple[str, int | None]
"""A sender as accepted: (IP in canonical form, port or None for any port)."""


def _canonical_ip(text: str, field_name: str, given: object) -> str:
    """``text`` as a canonical IP string (IPv4-mapped IPv6 as plain IPv4), or a ParameterError."""
    try:
        address = ipaddress.ip_address(text)
    except ValueError:
        raise ParameterError(f"NgimuConfig.{field_name} must be an IP address, optionally with a port "
                             f"(\"IP\", \"IP:port\", \"[IPv6]:port\" or (IP, port)), got {given!r}") from None
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
        return str(address.ipv4_mapped)
    return str(address)


def _checked_port(port: object, field_name: str) -> int:
    if isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= _MAX_PORT:
        raise ParameterError(f"NgimuConfig.{field_name} port must be an integer 1–{_MAX_PORT}, got {port!r}")
    return port


def parse_sender(value: object, field_name: str = "sender") -> SenderAddress:
    """The IMU's source address as (canonical IP, port or None).

    Parameters
    ----------
    value
        ``"IP"`` (any port), ``"IP:port"``, ``"[IPv6]:port"``, or an ``(IP, port)`` tuple; anything
        else is refused.
    field_name
        Named in the error message (e.g. ``"sender (--imu-sender)"``).

    Returns
    -------
    tuple
        (ip, port), port None when only the IP was given.

    Raises
    ------
    ParameterError
        Naming ``field_name`` when ``value`` is not an IP address, optionally with a port 1–65535.
    """
    if isinstance(value, tuple):
        if len(value) != 2 or not isinstance(value[0], str):
            raise ParameterError(f"NgimuConfig.{field_name} must be (IP, port), got {value!r}")
        return _canonical_ip(value[0], field_name, value), _checked_port(value[1], field_name)
    if not isinstance(value, str):
        raise ParameterError(f"NgimuConfig.{field_name} must be \"IP\", \"IP:port\" or (IP, port), "
                             f"got {value!r}")
    host, port_text = value, ""
    if value.startswith("[") and "]:" in value:  # [IPv6]:port
        host, _, port_text = value[1:].partition("]:")
    elif value.count(":") == 1:  # IPv4:port (a bare IPv6 address has at least two colons)
        host, _, port_text = value.partition(":")
    ip = _canonical_ip(host, field_name, value)
    if not port_text:
        return ip, None
    try:
        port = int(port_text)
    except ValueError:
        raise ParameterError(f"NgimuConfig.{field_name} port must be an integer 1–{_MAX_PORT}, "
                             f"got {port_text!r} in {value!r}") from None
    return ip, _checked_port(port, field_name)


def _as_text(value: object) -> str:
    """``value`` if it is a string; else a string that is no IP address (for the error path)."""
    return value if isinstance(value, str) else repr(value)


def _format_sender(sender: SenderAddress) -> str:
    ip, port = sender
    if port is None:
        return ip
    return f"[{ip}]:{port}" if ":" in ip else f"{ip}:{port}"


def _source_ip(host: str) -> str:
    """The IP of a received datagram's source as :func:`parse_sender` writes it (IPv4-mapped → IPv4)."""
    if host.startswith("::ffff:") and "." in host:
        return host[7:]
    return host


@dataclass(frozen=True, kw_only=True)
class NgimuConfig:
    """Where to listen, whom to listen to, and how to turn orientation into elevation.

    Parameters
    ----------
    host, port
        Address to bind: loopback by default (the simulated suit); on the real suit the address of
        the suit's interface the IMU sends to (``0.0.0.0``: every interface). Port 0: any free port,
        see :attr:`NgimuClient.address`.
    sender
        Accept datagrams only from this source: ``"IP"`` (any port), ``"IP:port"``,
        ``"[IPv6]:port"`` or ``(IP, port)``. None: from the first source whose datagram is OSC,
        locked in from then on (logged once).
    max_datagrams_per_read
        Datagrams taken from the socket per :meth:`NgimuClient.read` at most, whatever their source
        (a flood cannot hold the loop; the rest waits for the next call). The default catches up with
        a 400 Hz IMU sending two messages after a 0.3 s stall of the host in one read.
    parse_newest
        Of the IMU's datagrams taken in one read, only this many newest are parsed (after a stall, the
        older ones describe an arm that has moved on; parsing is the costly part, ~15 µs each).
    gyro_max_age_s
        A gyro reading older than this (s, on the client clock) is not used for velocity.
    min_elevation_for_gyro_rad
        Below this elevation the gyro axis is ill-defined; velocity comes from the difference.
    velocity_cutoff_hz
        Corner frequency of the difference-velocity low-pass.
    """

    host: str = "127.0.0.1"
    port: int = DEFAULT_HOST_PORT
    sender: tuple[str, int] | str | None = None
    max_datagrams_per_read: int = 256
    parse_newest: int = 16
    gyro_max_age_s: float = 0.02
    min_elevation_for_gyro_rad: float = math.radians(5.0)
    velocity_cutoff_hz: float = 20.0

    def __post_init__(self) -> None:
        try:
            ipaddress.ip_address(_as_text(self.host))
        except ValueError:
            raise ParameterError(f"NgimuConfig.host must be an IP address to bind, got {self.host!r}")\
                from None
        if self.sender is not None:
            parse_sender(self.sender)
        for name in ("port", "max_datagrams_per_read", "parse_newest"):
            value: object = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise ParameterError(f"NgimuConfig.{name} must be an integer, got {value!r}")
        for name in ("max_datagrams_per_read", "parse_newest"):
            if getattr(self, name) < 1:
                raise ParameterError(f"NgimuConfig.{name} must be >= 1, got {getattr(self, name)}")
        if not 0 <= self.port <= _MAX_PORT:
            raise ParameterError(f"NgimuConfig.port must be 0..{_MAX_PORT}, got {self.port}")
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
    """Datagrams and messages seen, and why some were dropped.

    ``datagrams`` counts what was taken from the IMU (and, before a sender is locked in, what was not
    OSC at all); ``foreign`` what came from any other source and was dropped unparsed.
    """

    datagrams: int = 0
    malformed: int = 0  # not OSC at all, or a packet that does not parse
    bad_messages: int = 0  # a known address with the wrong arguments
    unknown_addresses: int = 0
    foreign: int = 0  # datagrams from a source other than the IMU, dropped unparsed
    skipped_backlog: int = 0  # older datagrams of the IMU in one read, not parsed (after a stall)
    read_limit_hits: int = 0  # reads that took the most allowed (datagrams may be left on the socket)
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
        Monotonic clock (s) stamping each sample when it is taken in from the socket; the loop's
        clock.

    Notes
    -----
    Thread-safe: one thread at a time takes datagrams in (under a lock). :meth:`read` never waits for
    that lock: while another thread (a console, a calibration) is taking datagrams in, it returns the
    newest sample without touching the socket.
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
        self._collecting: list[tuple[float, float, float, float]] | None = None
        self._socket: socket.socket | None = None
        self._lock = threading.Lock()  # one taker of datagrams at a time (loop, console, calibration)
        self._allowed: SenderAddress | None = (
            parse_sender(self.config.sender) if self.config.sender is not None else None
        )
        self._foreign_seen: set[tuple[str, int]] = set()

    # --- lifecycle -------------------------------------------------------------------------------
    def start(self) -> Self:
        """Bind the UDP port, non-blocking (datagrams are taken in by :meth:`read`); no thread.

        Raises
        ------
        OSError
            If the address cannot be bound (in use, not an address of this host).
        """
        with self._lock:
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
        """Close the socket (after a take-in under way in another thread has finished)."""
        with self._lock:
            if self._socket is not None:
                self._socket.close()
                self._socket = None

    @property
    def address(self) -> tuple[str, int]:
        """The bound (host, port); useful with port 0."""
        sock = self._socket
        if sock is None:
            raise ParameterError("NgimuClient is not started")
        host, port = sock.getsockname()[:2]
        return str(host), int(port)

    @property
    def sender(self) -> SenderAddress | None:
        """The source accepted, (IP, port or None for any port): configured, or locked in on the first
        OSC datagram; None until then."""
        return self._allowed

    # --- ElevationSensor -------------------------------------------------------------------------
    def read(self) -> ElevationSample | None:
        """Take in what arrived (non-blocking, bounded) and return the latest elevation sample.

        Returns
        -------
        ElevationSample or None
            The newest sample, stamped when it was taken in; None before calibration or before the
            first ``/quaternion``.
        """
        self.poll()
        return self._latest

    def poll(self) -> int:
        """Take in the datagrams waiting on the socket, at most ``max_datagrams_per_read``.

        Returns
        -------
        int
            How many datagrams were taken from the socket (from any source). 0 when nothing waited,
            when the client is not started, or when another thread is taking datagrams in.
        """
        if not self._lock.acquire(blocking=False):
            return 0
        try:
            return self._take_in()
        finally:
            self._lock.release()

    def _take_in(self) -> int:
        """:meth:`poll` with the lock held."""
        sock = self._socket
        if sock is None:
            return 0
        limit = self.config.max_datagrams_per_read
        received: list[tuple[bytes, tuple[str, int]]] = []
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
        accepted = [(data, source) for data, source in received if self._admit(data, source)]
        skipped = len(accepted) - self.config.parse_newest
        if skipped > 0:
            self.counters.skipped_backlog += skipped
            self.counters.datagrams += skipped
            accepted = accepted[skipped:]
        for data, source in accepted:
            self._dispatcher.call_handlers_for_packet(data, source)
        return len(received)

    def calibrate_arm_down(self, duration_s: float = 1.0, *, min_samples: int = 10) -> ArmDownCalibration:
        """Average the orientation while the arm hangs still for ``duration_s`` and use it.

        Polls the socket itself, with short sleeps, until ``duration_s`` of wall time (monotonic, not
        the injected clock) is over. What was sent before the call is taken in but not collected.

        Parameters
        ----------
        duration_s
            How long the arm hangs still (s).
        min_samples
            Orientations needed at least.

        Returns
        -------
        ArmDownCalibration
            The humeral axis, also stored in :attr:`calibration`.

        Raises
        ------
        ParameterError
            If the client is not started, or for a non-positive duration or sample count.
        DeviceTimeoutError
            If fewer than ``min_samples`` orientations arrived (IMU not streaming to this host?).
        """
        if not (math.isfinite(duration_s) and duration_s > 0.0):
            raise ParameterError(f"calibration duration_s must be positive, got {duration_s!r}")
        if min_samples < 1:
            raise ParameterError(f"calibration min_samples must be >= 1, got {min_samples!r}")
        if self._socket is None:
            raise ParameterError("NgimuClient is not started: start it before calibrating")
        port = self.address[1]
        limit = self.config.max_datagrams_per_read
        for _ in range(16):  # what was sent before the call describes the arm before the pose
            if self._poll_waiting() < limit:
                break
        self._collecting = []
        end = time.monotonic() + duration_s
        try:
            while time.monotonic() < end:
                self._poll_waiting()
                time.sleep(_CALIBRATION_POLL_S)
            self._poll_waiting()
        finally:
            collected, self._collecting = self._collecting, None
        if len(collected) < min_samples:
            raise DeviceTimeoutError(
                f"NGIMU calibration got {len(collected)} orientations in {duration_s} s "
                f"(need {min_samples}): is the IMU sending /quaternion to port {port}"
                + ("" if self._allowed is None else f" from {_format_sender(self._allowed)}") + "?"
            )
        self.calibration = ArmDownCalibration.from_quaternions(collected)
        _log.info("NGIMU arm-down calibration: humeral axis %s", self.calibration.axis)
        return self.calibration

    def handle_datagram(self, data: bytes, sender: tuple[str, int] = ("127.0.0.1", 0)) -> None:
        """Process one UDP payload as if it had arrived from ``sender`` (:meth:`read` takes the same
        path: the sender check, then python-osc)."""
        with self._lock:
            if self._admit(data, (str(sender[0]), int(sender[1]))):
                self._dispatcher.call_handlers_for_packet(data, sender)

    # --- intake ----------------------------------------------------------------------------------
    def _poll_waiting(self) -> int:
        """:meth:`poll`, but waiting for the lock (the calibration must not skip its polls)."""
        with self._lock:
            return self._take_in()

    def _admit(self, data: bytes, source: tuple[str, int]) -> bool:
        """True if ``data`` comes from the IMU (locking the first OSC source in); count the rest."""
        ip = _source_ip(source[0])
        allowed = self._allowed
        if allowed is None:
            if not _is_osc(data):
                self.counters.datagrams += 1
                self.counters.malformed += 1
                return False
            self._allowed = allowed = (ip, source[1])
            _log.info("NGIMU: accepting only %s from now on", _format_sender(allowed))
        if ip == allowed[0] and (allowed[1] is None or source[1] == allowed[1]):
            return True
        self.counters.foreign += 1
        key = (ip, source[1])
        seen = self._foreign_seen
        if key not in seen and len(seen) <= _FOREIGN_SOURCES_LOGGED:
            seen.add(key)
            if len(seen) <= _FOREIGN_SOURCES_LOGGED:
                _log.warning("NGIMU: ignoring datagrams from %s (not the IMU, %s)",
                             _format_sender(key), _format_sender(allowed))
            else:
                _log.warning("NGIMU: datagrams from more than %d other sources; no longer logging them "
                             "(counted as foreign)", _FOREIGN_SOURCES_LOGGED)
        return False

    # --- handlers (called while taking datagrams in) ---------------------------------------------
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
