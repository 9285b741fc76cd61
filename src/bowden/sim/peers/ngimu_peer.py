"""A simulated NGIMU strapped to the upper arm, sending real OSC bundles over UDP.

At ``rate_hz`` it reads the arm's elevation from the simulated plant and sends what an NGIMU would:
one bundle with ``/sensors`` (gyro °/s, accelerometer g, magnetometer µT, barometer hPa, all in the
sensor frame) and one with ``/quaternion`` (w, x, y, z; sensor → earth, North-West-Up), each with an
NTP time tag (NGIMU user manual, "OSC messages").

The arm raises in a vertical plane at heading ``heading_rad`` (flexion when 0: the humerus swings
from straight down towards North), and the sensor sits on the arm with an arbitrary ``mounting``
rotation, unknown to the client, which has to find the humeral axis by its arm-down calibration:
q_sensor = q_heading ⊗ q_elevation(θ) ⊗ q_mounting.

Fault injection: :meth:`NgimuPeer.pause` (the stream stops), :meth:`NgimuPeer.send_nan`,
:meth:`NgimuPeer.hold_arm_down` (report a hanging arm, for the calibration).
"""

from __future__ import annotations

import math
import socket
import threading
import time
from collections.abc import Callable
from typing import Self

from pythonosc.osc_bundle_builder import OscBundleBuilder
from pythonosc.osc_message_builder import OscMessageBuilder

from bowden.errors import ParameterError
from bowden.hardware.elevation import (
    Quaternion,
    quaternion_conjugate,
    quaternion_from_axis_angle,
    quaternion_multiply,
    rotate,
)
from bowden.hardware.lifecycle import StartedInWith, StoppableThread
from bowden.hardware.ngimu import QUATERNION_ADDRESS, SENSORS_ADDRESS
from bowden.sim.peers.wall_time import WallTimePlant

# An arbitrary, asymmetric strap-on rotation: the client must not depend on how the IMU is mounted.
DEFAULT_MOUNTING: Quaternion = quaternion_from_axis_angle((0.3, -0.8, 0.5), math.radians(70.0))
_EARTH_FIELD_UT = (20.0, 0.0, -45.0)  # a mid-latitude field in NWU, µT
_SEA_LEVEL_HPA = 1013.25


def arm_orientation(elevation_rad: float, heading_rad: float, mounting: Quaternion) -> Quaternion:
    """Sensor orientation (sensor → earth) for an arm elevated by ``elevation_rad`` in its plane."""
    q_heading = quaternion_from_axis_angle((0.0, 0.0, 1.0), heading_rad)
    # Rotating about +y by −θ swings the downward humerus (0, 0, −1) to (sin θ, 0, −cos θ).
    q_elevation = quaternion_from_axis_angle((0.0, 1.0, 0.0), -elevation_rad)
    return quaternion_multiply(quaternion_multiply(q_heading, q_elevation), mounting)


def arm_gyro_rad_s(
    orientation: Quaternion, elevation_velocity_rad_s: float, heading_rad: float
) -> tuple[float, float, float]:
    """Body-frame angular velocity (rad/s) of the arm elevating at ``elevation_velocity_rad_s``."""
    axis_world = rotate(quaternion_from_axis_angle((0.0, 0.0, 1.0), heading_rad), (0.0, 1.0, 0.0))
    omega_world = (
        -elevation_velocity_rad_s * axis_world[0],
        -elevation_velocity_rad_s * axis_world[1],
        -elevation_velocity_rad_s * axis_world[2],
    )
    return rotate(quaternion_conjugate(orientation), omega_world)


class NgimuPeer(StartedInWith):
    """Streams the simulated arm as NGIMU OSC bundles to ``target``.

    Parameters
    ----------
    plant
        The shared simulated suit.
    target
        (host, port) of the client (NGIMU default host port: 8000).
    rate_hz
        Message rate (NGIMU: settable per message, up to several hundred Hz).
    heading_rad, mounting
        Plane of elevation and strap-on rotation (see the module docstring).
    time_source
        Wall clock pacing the stream.
    """

    def __init__(
        self,
        plant: WallTimePlant,
        target: tuple[str, int],
        *,
        rate_hz: float = 200.0,
        heading_rad: float = 0.4,
        mounting: Quaternion = DEFAULT_MOUNTING,
        time_source: Callable[[], float] = time.monotonic,
    ) -> None:
        if not (math.isfinite(rate_hz) and 0.0 < rate_hz <= 1000.0):
            raise ParameterError(f"rate_hz must be in (0, 1000], got {rate_hz}")
        self._plant = plant
        self.target = target
        self.rate_hz = rate_hz
        self.heading_rad = heading_rad
        self.mounting = mounting
        self._time_source = time_source
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._paused = threading.Event()
        self._nan = threading.Event()
        self._arm_down = threading.Event()
        self._frozen: tuple[float, float] | None = None
        self._streamer = StoppableThread(self._stream, "ngimu-peer")
        self.sent = 0
        self.last_sent_wall_s = math.nan  # time.time() after the last bundle left (a silence starts there)
        self._sent_changed = threading.Condition()

    def start(self) -> Self:
        """Start streaming in a background thread."""
        self._streamer.start()
        return self

    def close(self) -> None:
        """Stop streaming and close the socket."""
        self._streamer.stop()
        self._socket.close()

    def pause(self, paused: bool = True) -> None:
        """Stop (or resume) sending, as an IMU out of battery or out of Wi-Fi range."""
        if paused:
            self._paused.set()
        else:
            self._paused.clear()

    def send_nan(self, enabled: bool = True) -> None:
        """Send NaN quaternions (a diverged filter) instead of the arm's orientation."""
        if enabled:
            self._nan.set()
        else:
            self._nan.clear()

    def hold_arm_down(self, enabled: bool = True) -> None:
        """Report a still, hanging arm whatever the plant does (the calibration pose)."""
        if enabled:
            self._arm_down.set()
        else:
            self._arm_down.clear()

    def freeze(self, frozen: bool = True) -> None:
        """Keep sending the arm's current orientation, still, whatever the plant does (an IMU that
        came off the arm and lies on the table); False follows the arm again."""
        if frozen:
            sample = self._plant.elevation()
            self._frozen = (sample.elevation_rad if sample is not None else 0.0, 0.0)
        else:
            self._frozen = None

    def wait_until_sent(self, timeout_s: float = 5.0) -> None:
        """Return once a state read *after* this call has been sent, so that a fault set before it
        (:meth:`hold_arm_down`, :meth:`send_nan`, :meth:`freeze`, resuming from :meth:`pause`) is on
        the wire, and nothing from before it is still to come: the stream thread may have read the
        state before the change and be about to send it (a preempted thread on a busy host).

        Raises
        ------
        TimeoutError
            Nothing was sent within ``timeout_s`` (paused, or not started).
        """
        with self._sent_changed:
            # The bundle in flight may hold the old state; the one after it was read after this call.
            target = self.sent + 2
            if not self._sent_changed.wait_for(lambda: self.sent >= target, timeout_s):
                raise TimeoutError(f"the simulated IMU sent nothing new within {timeout_s:g} s")

    def datagrams(self, elevation_rad: float, elevation_velocity_rad_s: float) -> tuple[bytes, bytes]:
        """The two bundles (``/sensors``, ``/quaternion``) for one arm state."""
        q = arm_orientation(elevation_rad, self.heading_rad, self.mounting)
        if self._nan.is_set():
            q = (math.nan, math.nan, math.nan, math.nan)
        gyro = arm_gyro_rad_s(q, elevation_velocity_rad_s, self.heading_rad)
        accel = rotate(quaternion_conjugate(q), (0.0, 0.0, 1.0))  # at rest, +1 g along earth up
        mag = rotate(quaternion_conjugate(q), _EARTH_FIELD_UT)
        stamp = time.time()
        sensors = OscMessageBuilder(address=SENSORS_ADDRESS)
        for value in (*(math.degrees(w) for w in gyro), *accel, *mag, _SEA_LEVEL_HPA):
            sensors.add_arg(float(value), OscMessageBuilder.ARG_TYPE_FLOAT)
        quaternion = OscMessageBuilder(address=QUATERNION_ADDRESS)
        for value in q:
            quaternion.add_arg(float(value), OscMessageBuilder.ARG_TYPE_FLOAT)
        out = []
        for message in (sensors, quaternion):
            bundle = OscBundleBuilder(stamp)  # type: ignore[arg-type]  # python-osc takes float seconds
            bundle.add_content(message.build())
            out.append(bundle.build().dgram)
        return out[0], out[1]

    def _stream(self) -> None:
        period = 1.0 / self.rate_hz
        deadline = self._time_source()
        while not self._streamer.stop_requested.is_set():
            deadline += period
            remaining = deadline - self._time_source()
            if remaining > 0.0:
                time.sleep(remaining)
            else:
                deadline = self._time_source()  # fell behind: keep the rate, do not burst
            if self._paused.is_set():
                continue
            frozen = self._frozen
            if self._arm_down.is_set():
                elevation, velocity = 0.0, 0.0
            elif frozen is not None:
                elevation, velocity = frozen
            else:
                sample = self._plant.elevation()
                if sample is None:
                    continue
                elevation, velocity = sample.elevation_rad, sample.elevation_velocity_rad_s
            self._emit(elevation, velocity)
            with self._sent_changed:
                self.last_sent_wall_s = time.time()
                self.sent += 1
                self._sent_changed.notify_all()

    def _emit(self, elevation_rad: float, elevation_velocity_rad_s: float) -> None:
        """Send one arm state (the LSL peer, :mod:`bowden.sim.peers.lsl_imu_peer`, pushes it instead)."""
        for datagram in self.datagrams(elevation_rad, elevation_velocity_rad_s):
            try:
                self._socket.sendto(datagram, self.target)
            except OSError:
                continue  # nobody listening yet (ICMP port unreachable): a real IMU sends anyway
