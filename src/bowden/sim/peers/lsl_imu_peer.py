"""A simulated IMU on the upper arm streaming its orientation into Lab Streaming Layer.

It stands for an Xsens, Movella DOT or BNO08x board behind an LSL bridge (``--imu lsl:NAME``): at
``rate_hz`` it publishes the arm's orientation as a 4-channel quaternion stream (w, x, y, z; sensor →
earth, z up, the same strap-on rotation as :class:`~bowden.sim.peers.NgimuPeer`, which it extends), or
with ``kind="elevation"`` a 1-channel elevation stream in degrees (channel unit ``degrees``). Every
fault of the NGIMU peer works the same (``pause``, ``send_nan``, ``hold_arm_down``, ``freeze``).
"""

from __future__ import annotations

import math
from typing import Any

from bowden.errors import ParameterError
from bowden.hardware.lsl_imu import pylsl_module
from bowden.sim.peers.ngimu_peer import NgimuPeer, arm_orientation
from bowden.sim.peers.wall_time import WallTimePlant


class LslImuPeer(NgimuPeer):
    """Publishes the simulated arm on an LSL outlet named ``stream_name`` (see the module)."""

    def __init__(self, plant: WallTimePlant, stream_name: str, *, kind: str = "quaternion",
                 rate_hz: float = 200.0, **options: Any) -> None:
        if kind not in ("quaternion", "elevation"):
            raise ParameterError(f"kind must be quaternion or elevation, got {kind!r}")
        super().__init__(plant, ("127.0.0.1", 9), rate_hz=rate_hz, **options)
        pylsl = pylsl_module()
        channels = 4 if kind == "quaternion" else 1
        info = pylsl.StreamInfo(stream_name, "Orientation" if channels == 4 else "Elevation", channels,
                                rate_hz, pylsl.cf_float32, f"bowden-sim-imu-{stream_name}")
        if kind == "elevation":
            info.desc().append_child("channels").append_child("channel").append_child_value(
                "label", "elevation").append_child_value("unit", "degrees")
        self.kind = kind
        self._outlet = pylsl.StreamOutlet(info)

    def _emit(self, elevation_rad: float, elevation_velocity_rad_s: float) -> None:
        if self.kind == "elevation":
            value = math.nan if self._nan.is_set() else math.degrees(elevation_rad)
            self._outlet.push_sample([value])
            return
        q = arm_orientation(elevation_rad, self.heading_rad, self.mounting)
        if self._nan.is_set():
            q = (math.nan, math.nan, math.nan, math.nan)
        self._outlet.push_sample(list(q))

    def close(self) -> None:
        super().close()
        self._outlet = None  # liblsl withdraws the stream when its outlet goes
