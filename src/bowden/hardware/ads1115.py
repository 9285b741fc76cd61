"""Load cell through an ADS1115 16-bit ADC over I²C (smbus2), read in its own thread.

Register map (TI ADS1115 datasheet SBAS444, §9.6): pointer 0 = conversion (int16, big-endian),
1 = config, 2/3 = comparator thresholds. Config bits: OS[15] (start single shot / conversion done),
MUX[14:12] (0: AIN0−AIN1 differential), PGA[11:9] (full scale ±6.144, 4.096, 2.048, 1.024, 0.512,
0.256 V), MODE[8] (0 continuous, 1 single shot), DR[7:5] (8…860 SPS), COMP_*[4:0] (3 in COMP_QUE
disables the comparator).

In continuous mode the conversion register always holds the latest result, so a read returns at once;
single shot would busy-wait 1/rate per sample (TI ADS1115 data sheet, SBAS444, "Operating modes"). The
reader thread polls at the data rate and time-stamps each value with the loop's clock; the control loop
only ever takes the latest sample, so I²C never blocks it. The load cell is for evaluation: the
controller never needs it.

Registers go over SMBus block transfers (big-endian as on the wire): SMBus "word" transfers are
little-endian and would swap the bytes.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Final, Protocol, Self

from bowden.errors import DeviceTimeoutError, HardwareError, MalformedFrameError, ParameterError
from bowden.hardware.lifecycle import StartedInWith, StoppableThread
from bowden.hardware.protocols import TensionSample

_log = logging.getLogger(__name__)

REG_CONVERSION: Final = 0x00
REG_CONFIG: Final = 0x01
REG_LO_THRESH: Final = 0x02
REG_HI_THRESH: Final = 0x03
DEFAULT_ADDRESS: Final = 0x48
DEFAULT_CONFIG: Final = 0x8583  # power-on value: single shot, AIN0−AIN1, ±2.048 V, 128 SPS
FULL_SCALE_V: Final = (6.144, 4.096, 2.048, 1.024, 0.512, 0.256, 0.256, 0.256)  # by PGA code
DATA_RATES_SPS: Final = (8, 16, 32, 64, 128, 250, 475, 860)  # by DR code
OS_BIT: Final = 1 << 15
MODE_SINGLE_SHOT: Final = 1 << 8
COMPARATOR_DISABLED: Final = 0b11


class SMBusLike(Protocol):
    """The part of ``smbus2.SMBus`` the driver uses (the simulated bus implements it too)."""

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int,
                            force: bool | None = None) -> list[int]: ...

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: Sequence[int],
                             force: bool | None = None) -> None: ...


def encode_config(*, mux: int, pga: int, continuous: bool, data_rate: int, start: bool = False) -> int:
    """The 16-bit config word (comparator disabled)."""
    for name, value, top in (("mux", mux, 7), ("pga", pga, 7), ("data_rate", data_rate, 7)):
        if not 0 <= value <= top:
            raise ParameterError(f"ADS1115 {name} code must be 0..{top}, got {value}")
    word = (mux << 12) | (pga << 9) | (data_rate << 5) | COMPARATOR_DISABLED
    if not continuous:
        word |= MODE_SINGLE_SHOT
    if start:
        word |= OS_BIT
    return word


def register_bytes(word: int) -> list[int]:
    """A 16-bit register value as the two bytes on the wire (MSB first)."""
    return [(word >> 8) & 0xFF, word & 0xFF]


def word_from_bytes(data: Sequence[int]) -> int:
    """Two wire bytes (MSB first) as an unsigned 16-bit value.

    Raises
    ------
    MalformedFrameError
        Unless ``data`` is exactly two integers in 0..255.
    """
    if len(data) != 2 or not all(isinstance(b, int) and 0 <= b <= 0xFF for b in data):
        raise MalformedFrameError(f"ADS1115 register read must be 2 bytes, got {list(data)!r}")
    return (data[0] << 8) | data[1]


def conversion_to_volts(data: Sequence[int], full_scale_v: float) -> float:
    """Conversion register bytes → volts: int16 two's complement × FS/32768."""
    code = word_from_bytes(data)
    if code >= 0x8000:
        code -= 0x10000
    volts: float = code_to_volts(code, full_scale_v)
    return volts


def code_to_volts(code: Any, full_scale_v: float) -> Any:
    """A signed 16-bit conversion code (an int or an integer array) → volts, code × FS/32768.

    The one formula the driver reads with; the simulation and the store's grid filter
    (:mod:`bowden.store.sensor_grids`) use it too, so their values equal the driver's bit for bit.
    """
    return code * full_scale_v / 32768.0


@dataclass(frozen=True, kw_only=True)
class LoadCellCalibration:
    """tension_n = (volts − offset_v) · gain_n_per_v (amplifier + load cell, e.g. Futek LSB201 + IAA100)."""

    offset_v: float = 0.0
    gain_n_per_v: float = 100.0

    def __post_init__(self) -> None:
        if not math.isfinite(self.offset_v):
            raise ParameterError(f"LoadCellCalibration.offset_v must be finite, got {self.offset_v!r}")
        if not (math.isfinite(self.gain_n_per_v) and self.gain_n_per_v != 0.0):
            raise ParameterError(
                f"LoadCellCalibration.gain_n_per_v must be finite and non-zero, got {self.gain_n_per_v!r}"
            )

    @classmethod
    def from_two_points(cls, *, volts_1: float, tension_1_n: float, volts_2: float,
                        tension_2_n: float) -> LoadCellCalibration:
        """The line through two (volts, known tension) points, e.g. unloaded and a hanging weight."""
        if volts_2 == volts_1:
            raise ParameterError("calibration points need different voltages")
        gain = (tension_2_n - tension_1_n) / (volts_2 - volts_1)
        return cls(offset_v=volts_1 - tension_1_n / gain, gain_n_per_v=gain)

    def tension_n(self, volts: Any) -> Any:
        """Tension (N) for a reading (V; a float or an array, element-wise the same arithmetic)."""
        return (volts - self.offset_v) * self.gain_n_per_v


@dataclass(frozen=True, kw_only=True)
class ADS1115Config:
    """Address, input, range and rate.

    Parameters
    ----------
    address
        I²C address (0x48–0x4B by the ADDR pin).
    mux
        Input multiplexer code (0: AIN0−AIN1 differential).
    pga
        Gain code; full scale ``FULL_SCALE_V[pga]`` volts.
    data_rate
        Rate code; ``DATA_RATES_SPS[data_rate]`` samples/s (7: 860 SPS).
    max_consecutive_errors, lost_after_s
        The reader stops and reports the sensor lost after at least this many failed reads in a row
        spanning at least this long (s): failed attempts, so a reader thread that was not scheduled
        is not a lost sensor.
    """

    address: int = DEFAULT_ADDRESS
    mux: int = 0
    pga: int = 1
    data_rate: int = 7
    max_consecutive_errors: int = 3
    lost_after_s: float = 0.02

    def __post_init__(self) -> None:
        if not 0x48 <= self.address <= 0x4B:
            raise ParameterError(f"ADS1115Config.address must be 0x48..0x4B, got {self.address:#x}")
        encode_config(mux=self.mux, pga=self.pga, continuous=True, data_rate=self.data_rate)
        if self.max_consecutive_errors < 1:
            raise ParameterError("ADS1115Config.max_consecutive_errors must be >= 1")
        if not (math.isfinite(self.lost_after_s) and self.lost_after_s >= 0.0):
            raise ParameterError(f"ADS1115Config.lost_after_s must be ≥ 0, got {self.lost_after_s!r}")

    @property
    def full_scale_v(self) -> float:
        return FULL_SCALE_V[self.pga]

    @property
    def sample_rate_hz(self) -> float:
        return float(DATA_RATES_SPS[self.data_rate])


@dataclass
class ADS1115Counters:
    samples: int = 0
    io_errors: int = 0
    malformed: int = 0


class ADS1115LoadCell(StartedInWith):
    """The load cell as a :class:`~bowden.hardware.TensionSensor`.

    Parameters
    ----------
    bus
        An open ``smbus2.SMBus`` (or compatible); the caller owns it.
    config, calibration
        See :class:`ADS1115Config` and :class:`LoadCellCalibration`.
    clock
        The loop's monotonic clock (s), stamping each sample.
    """

    def __init__(
        self,
        bus: SMBusLike,
        config: ADS1115Config | None = None,
        calibration: LoadCellCalibration | None = None,
        *,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._bus = bus
        self.config = config if config is not None else ADS1115Config()
        self.calibration = calibration if calibration is not None else LoadCellCalibration()
        self._clock = clock
        self.counters = ADS1115Counters()
        self._latest: TensionSample | None = None
        self._latest_volts = math.nan
        self.failure: str | None = None  # set by the reader when it gives up; the loop reads it
        self._poller = StoppableThread(self._poll, "ads1115")

    def start(self) -> Self:
        """Configure continuous conversion, check it took, and start the reader thread.

        Raises
        ------
        HardwareError
            If the ADC does not answer or does not keep the configuration.
        """
        if self._poller.running:
            return self
        c = self.config
        word = encode_config(mux=c.mux, pga=c.pga, continuous=True, data_rate=c.data_rate)
        try:
            self._bus.write_i2c_block_data(c.address, REG_CONFIG, register_bytes(word))
            readback = word_from_bytes(self._bus.read_i2c_block_data(c.address, REG_CONFIG, 2))
        except OSError as error:
            raise HardwareError(f"ADS1115 at {c.address:#x} does not answer on I²C: {error}") from error
        if readback & ~OS_BIT != word & ~OS_BIT:
            raise HardwareError(
                f"ADS1115 at {c.address:#x} did not keep its configuration "
                f"(wrote {word:#06x}, read {readback:#06x}): is it an ADS1115?"
            )
        self._poller.start()
        return self

    def close(self) -> None:
        """Stop the thread and put the ADC back into single-shot (power-down) mode."""
        if self._poller.running:
            self._poller.stop()
            try:
                self._bus.write_i2c_block_data(self.config.address, REG_CONFIG, register_bytes(DEFAULT_CONFIG
                                                                                                & ~OS_BIT))
            except OSError as error:
                _log.warning("ADS1115: could not power down (%s)", error)

    def read(self) -> TensionSample | None:
        """The latest tension sample (never blocks), or None before the first conversion."""
        return self._latest

    @property
    def latest_volts(self) -> float:
        """The latest reading in volts (NaN before the first), for calibration."""
        return self._latest_volts

    def tare(self, duration_s: float = 0.5) -> LoadCellCalibration:
        """Zero the offset on the mean reading over ``duration_s`` (cable slack) and use it.

        Raises
        ------
        DeviceTimeoutError
            If no reading arrived in that time.
        """
        volts: list[float] = []
        end = time.monotonic() + duration_s
        last: TensionSample | None = None
        while time.monotonic() < end:
            sample = self._latest
            if sample is not None and sample is not last:
                volts.append(self._latest_volts)
                last = sample
            time.sleep(0.5 / self.config.sample_rate_hz)
        if not volts:
            raise DeviceTimeoutError(f"ADS1115 gave no reading in {duration_s} s of taring")
        offset = sum(volts) / len(volts)
        self.calibration = LoadCellCalibration(offset_v=offset, gain_n_per_v=self.calibration.gain_n_per_v)
        return self.calibration

    def _poll(self) -> None:
        period = 1.0 / self.config.sample_rate_hz
        full_scale = self.config.full_scale_v
        address = self.config.address
        errors = 0
        first_error_s = 0.0
        # The first result is ready one period after configuring; before that the conversion
        # register still holds its power-on 0, which would read as a real 0 V sample.
        deadline = time.monotonic() + 1.5 * period
        stop = self._poller.stop_requested
        if stop.wait(1.5 * period):
            return
        while not stop.is_set():
            try:
                data = self._bus.read_i2c_block_data(address, REG_CONVERSION, 2)
                volts = conversion_to_volts(data, full_scale)
            except (MalformedFrameError, OSError) as error:
                if isinstance(error, MalformedFrameError):
                    self.counters.malformed += 1
                else:
                    self.counters.io_errors += 1
                if errors == 0:
                    first_error_s = time.monotonic()
                errors += 1
            else:
                errors = 0
                self._latest_volts = volts
                self._latest = TensionSample(self._clock(), self.calibration.tension_n(volts))
                self.counters.samples += 1
            # Errors that are attempts which failed, not a reader that was not scheduled: the device.
            if errors >= self.config.max_consecutive_errors and \
                    time.monotonic() - first_error_s >= self.config.lost_after_s:
                self.failure = (f"ADS1115 at {address:#x}: {errors} I²C errors in a row over "
                                f"{1e3 * (time.monotonic() - first_error_s):.0f} ms, load cell lost")
                _log.error(self.failure)
                return
            deadline += period
            remaining = deadline - time.monotonic()
            if remaining > 0.0:
                stop.wait(remaining)
            else:
                deadline = time.monotonic()
