"""Any IMU that streams orientation into Lab Streaming Layer (``--imu lsl:STREAM_NAME``).

Xsens, Movella DOT, BNO08x boards and many others have LSL bridges; bowden reads their stream as it
reads the NGIMU (:mod:`bowden.hardware.ngimu`), with the same elevation computation
(:mod:`bowden.hardware.elevation`) and the same faults:

* a **quaternion stream** has 4 channels, (w, x, y, z), sensor → earth with z up (as the NGIMU's);
  elevation comes from the arm-down calibration (:meth:`LslImuClient.calibrate_arm_down`), velocity
  from the filtered difference of successive elevations (the NGIMU's fallback below 5°);
* an **elevation stream** has 1 channel, the humeral elevation in rad (or degrees when the stream's
  channel unit says ``deg``/``degrees``), computed by the device; the calibration then only checks
  that samples arrive.

The inlet is read without waiting (at most ``max_samples_per_read`` a call) and each sample is stamped
when it is taken in, so the loop's IMU watchdog (``--imu-max-age-ms``) judges it as the NGIMU's.
Its own staleness watchdog: LSL buffers a stream across a network dropout and then delivers the
backlog at once; a sample whose LSL time stamp (clock-synchronised to this host) is older than
``max_sample_age_s`` when it arrives describes an arm that has moved on, and is counted
(``counters.stale``) and not used — the last fresh sample ages instead, and the loop's watchdog
stops the suit. Non-finite samples are kept as such (the loop's ``NONFINITE_INPUT`` stops it).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Final, Self

from bowden.errors import DeviceTimeoutError, HardwareError, MissingExtraError, ParameterError
from bowden.hardware.elevation import (
    ArmDownCalibration,
    DifferenceVelocity,
    elevation_from_direction,
    humerus_direction,
    quaternion_normalised,
)
from bowden.hardware.lifecycle import StartedInWith
from bowden.hardware.protocols import ElevationSample

_log = logging.getLogger(__name__)
QUATERNION_CHANNELS: Final = 4
ELEVATION_CHANNELS: Final = 1
_DEGREE_UNITS: Final = ("deg", "degree", "degrees")
_CALIBRATION_POLL_S: Final = 0.005


def parse_imu(spec: str) -> str | None:
    """The LSL stream name of ``--imu lsl:NAME``, or None for ``--imu ngimu``.

    Raises
    ------
    ParameterError
        Naming ``--imu`` for anything else.
    """
    if spec == "ngimu":
        return None
    if spec.startswith("lsl:") and spec[4:].strip():
        return spec[4:].strip()
    raise ParameterError(f"--imu must be ngimu or lsl:STREAM_NAME, got {spec!r}")


@dataclass(frozen=True, kw_only=True)
class LslImuConfig:
    """Which stream, and how to read it.

    Parameters
    ----------
    stream_name
        The LSL stream's name (its ``name`` property).
    resolve_timeout_s
        How long to look for the stream when starting.
    max_sample_age_s
        A sample older than this (s, by its LSL time stamp) when it arrives is stale, not used.
    max_samples_per_read
        Samples taken from the inlet per :meth:`LslImuClient.read` at most (a backlog cannot hold
        the loop).
    velocity_cutoff_hz
        Corner frequency of the difference-velocity low-pass.
    """

    stream_name: str
    resolve_timeout_s: float = 5.0
    max_sample_age_s: float = 0.1
    max_samples_per_read: int = 64
    velocity_cutoff_hz: float = 20.0

    def __post_init__(self) -> None:
        if not self.stream_name:
            raise ParameterError("--imu lsl:STREAM_NAME needs a stream name")
        for name in ("resolve_timeout_s", "max_sample_age_s", "velocity_cutoff_hz"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ParameterError(f"LslImuConfig.{name} must be positive, got {value!r}")
        if self.max_samples_per_read < 1:
            raise ParameterError(
                f"LslImuConfig.max_samples_per_read must be >= 1, got {self.max_samples_per_read}"
            )


@dataclass
class LslImuCounters:
    """Samples seen, and why some were not used."""

    samples: int = 0
    stale: int = 0  # arrived older than max_sample_age_s (a backlog after a dropout)
    non_finite: int = 0
    quaternions: int = 0  # quaternions taken in (as NgimuCounters.quaternions; elevation samples too)


def pylsl_module() -> Any:
    try:
        import pylsl
    except ImportError:
        raise MissingExtraError(
            "--imu lsl:… needs the lsl extra (pylsl missing): pip install 'bowden[lsl]'"
        ) from None
    return pylsl


class LslImuClient(StartedInWith):
    """The elevation from an LSL orientation stream (implements :class:`~bowden.hardware.ElevationSensor`).

    Parameters
    ----------
    config
        :class:`LslImuConfig`.
    clock
        The loop's time source (s): samples are stamped with it when taken in.
    """

    def __init__(self, config: LslImuConfig, *, clock: Callable[[], float] = time.monotonic) -> None:
        self.config = config
        self._clock = clock
        self.counters = LslImuCounters()
        self.calibration: ArmDownCalibration | None = None
        self.kind = ""  # "quaternion" or "elevation", once started
        self.source = ""  # how the stream describes itself, for the run's summary
        self._inlet: Any = None
        self._local_clock: Callable[[], float] = time.monotonic
        self._degrees = False
        self._difference = DifferenceVelocity(config.velocity_cutoff_hz)
        self._latest: ElevationSample | None = None
        self._collecting: list[Sequence[float]] | None = None

    # --- lifecycle -------------------------------------------------------------------------------
    def start(self) -> Self:
        """Find the stream and open its inlet.

        Raises
        ------
        MissingExtraError
            pylsl is not installed.
        HardwareError
            No stream of that name within ``resolve_timeout_s`` (naming the streams that are
            visible), or a stream with neither 4 nor 1 channels.
        """
        if self._inlet is not None:
            return self
        pylsl = pylsl_module()
        name = self.config.stream_name
        found = pylsl.resolve_byprop("name", name, minimum=1, timeout=self.config.resolve_timeout_s)
        if not found:
            visible = sorted({info.name() for info in pylsl.resolve_streams(wait_time=0.5)})
            raise HardwareError(f"no LSL stream named {name!r} within {self.config.resolve_timeout_s:g} s "
                                f"(--imu lsl:{name}); visible: {', '.join(visible) or 'none'}")
        info = found[0]
        channels = info.channel_count()
        if channels not in (QUATERNION_CHANNELS, ELEVATION_CHANNELS):
            raise HardwareError(f"the LSL stream {name!r} has {channels} channels: bowden reads a quaternion "
                                "(4: w, x, y, z) or an elevation (1) stream")
        self._inlet = pylsl.StreamInlet(info, max_buflen=2, processing_flags=pylsl.proc_clocksync)
        # Connect and synchronise the clocks now: liblsl otherwise does both at the first pull and
        # holds every sample until its first clock offset is measured (≈ 0.65 s on one machine), so
        # the arm-down calibration that follows would get nothing, then only a stale backlog.
        try:
            self._inlet.open_stream(timeout=self.config.resolve_timeout_s)
            self._inlet.time_correction(timeout=self.config.resolve_timeout_s)
        except Exception as error:  # pylsl's TimeoutError/LostError; the inlet is of no use then
            self._inlet = None
            raise HardwareError(f"the LSL stream {name!r} was found but could not be opened within "
                                f"{self.config.resolve_timeout_s:g} s (--imu lsl:{name}): {error}") from None
        self._local_clock = pylsl.local_clock
        self.kind = "quaternion" if channels == QUATERNION_CHANNELS else "elevation"
        if self.kind == "elevation":
            self._degrees = self._unit(self._inlet) in _DEGREE_UNITS
        self.source = f"LSL {self.kind} stream {name!r} ({info.type() or 'no type'}) from {info.hostname()}"
        _log.info("IMU: reading %s", self.source)
        return self

    def close(self) -> None:
        inlet, self._inlet = self._inlet, None
        if inlet is not None:
            inlet.close_stream()

    @staticmethod
    def _unit(inlet: Any) -> str:
        try:
            channel = inlet.info(timeout=2.0).desc().child("channels").child("channel")
            return str(channel.child_value("unit")).strip().lower()
        except Exception:  # pylsl raises its own timeout and lost errors; the unit is optional
            return ""

    # --- ElevationSensor -------------------------------------------------------------------------
    def read(self) -> ElevationSample | None:
        """Take in what arrived (non-blocking, bounded) and return the latest fresh sample.

        None before the calibration (quaternion streams) or before the first fresh sample.
        """
        self.poll()
        return self._latest

    def poll(self) -> int:
        """Take in the waiting samples (at most ``max_samples_per_read``); how many were taken."""
        inlet = self._inlet
        if inlet is None:
            return 0
        samples, stamps = inlet.pull_chunk(timeout=0.0, max_samples=self.config.max_samples_per_read)
        if not samples:
            return 0
        now, lsl_now = self._clock(), self._local_clock()
        for values, stamp in zip(samples, stamps, strict=True):
            self._take(values, float(stamp), now, lsl_now)
        return len(samples)

    def _take(self, values: Sequence[float], stamp_s: float, now: float, lsl_now: float) -> None:
        self.counters.samples += 1
        self.counters.quaternions += 1
        if lsl_now - stamp_s > self.config.max_sample_age_s:
            self.counters.stale += 1
            return
        if self.kind == "quaternion":
            q = quaternion_normalised(values)
            if self._collecting is not None:
                self._collecting.append(q)
            if self.calibration is None:
                return
            elevation = elevation_from_direction(humerus_direction(q, self.calibration))
        else:
            elevation = float(values[0]) * (math.pi / 180.0 if self._degrees else 1.0)
            if self._collecting is not None:
                self._collecting.append((elevation,))
        if not math.isfinite(elevation):
            self.counters.non_finite += 1
        # The velocity is differentiated on the sender's time stamps: the intake times bunch up.
        velocity = self._difference.update(stamp_s, elevation)
        self._latest = ElevationSample(now, elevation, velocity if math.isfinite(elevation) else math.nan)

    def calibrate_arm_down(self, duration_s: float = 1.0, *,
                           min_samples: int = 10) -> ArmDownCalibration | None:
        """Average the orientation while the arm hangs still (quaternion streams; elevation streams:
        only check that samples arrive).

        Raises
        ------
        ParameterError
            If not started, or a non-positive duration.
        DeviceTimeoutError
            Fewer than ``min_samples`` fresh samples in ``duration_s``.
        """
        if not (math.isfinite(duration_s) and duration_s > 0.0):
            raise ParameterError(f"calibration duration_s must be positive, got {duration_s!r}")
        if self._inlet is None:
            raise ParameterError("LslImuClient is not started: start it before calibrating")
        while self.poll() >= self.config.max_samples_per_read:  # what came before the pose
            pass
        self._collecting = []
        end = time.monotonic() + duration_s
        try:
            while time.monotonic() < end:
                self.poll()
                time.sleep(_CALIBRATION_POLL_S)
            self.poll()
        finally:
            collected, self._collecting = self._collecting, None
        if len(collected) < min_samples:
            raise DeviceTimeoutError(f"IMU calibration got {len(collected)} samples from the LSL stream "
                                     f"{self.config.stream_name!r} in {duration_s:g} s (need {min_samples}): "
                                     "is the IMU streaming?")
        if self.kind == "elevation":
            return None
        self.calibration = ArmDownCalibration.from_quaternions(collected)
        return self.calibration
