"""A simulated ADS1115 on a fake, smbus2-compatible I²C bus, measuring the simulated cable tension.

The device keeps the real register map (TI SBAS444 §9.6): a pointer to one of four 16-bit registers
(big-endian on the wire), a config register that resets to 0x8583, continuous conversions at the
configured rate (the conversion register changes once per 1/rate and holds its value in between),
single-shot conversions started by writing OS = 1 (OS reads 0 while converting), the PGA full scale
and int16 saturation. Its input is the load-cell amplifier: volts = offset + sensitivity × tension.

:class:`FakeSMBus` stands where ``smbus2.SMBus`` would, with the same method signatures; an address
nobody answers gives ``OSError(EREMOTEIO)`` like the kernel's i2c-dev.
"""

from __future__ import annotations

import errno
import math
import threading
import time
from collections.abc import Callable, Sequence
from types import TracebackType
from typing import Self

from bowden.errors import ParameterError
from bowden.hardware.ads1115 import (
    DATA_RATES_SPS,
    DEFAULT_ADDRESS,
    DEFAULT_CONFIG,
    FULL_SCALE_V,
    MODE_SINGLE_SHOT,
    OS_BIT,
    REG_CONFIG,
    REG_CONVERSION,
    REG_HI_THRESH,
    REG_LO_THRESH,
)
from bowden.sim.peers.wall_time import WallTimePlant


class ADS1115Peer:
    """The ADC and the load-cell amplifier in front of it.

    Parameters
    ----------
    plant
        The shared simulated suit (its load cell gives the tension).
    address
        I²C address.
    offset_v, volts_per_newton
        Amplifier output at zero load and its sensitivity (V/N) on the AIN0−AIN1 input.
    time_source
        Wall clock deciding when conversions complete.
    """

    def __init__(
        self,
        plant: WallTimePlant,
        *,
        address: int = DEFAULT_ADDRESS,
        offset_v: float = 0.05,
        volts_per_newton: float = 0.01,
        time_source: Callable[[], float] = time.monotonic,
    ) -> None:
        if not (math.isfinite(volts_per_newton) and volts_per_newton != 0.0):
            raise ParameterError(f"volts_per_newton must be finite and non-zero, got {volts_per_newton}")
        self._plant = plant
        self.address = address
        self.offset_v = offset_v
        self.volts_per_newton = volts_per_newton
        self._time_source = time_source
        self._lock = threading.Lock()
        self._registers = {REG_CONVERSION: 0, REG_CONFIG: DEFAULT_CONFIG, REG_LO_THRESH: 0x8000,
                           REG_HI_THRESH: 0x7FFF}
        self._conversion_started_s = math.nan
        self._next_conversion_s = math.inf
        self._tension_override_n: float | None = None
        self._failures_left = 0
        self.reads = 0

    # --- fault injection -------------------------------------------------------------------------
    def override_tension_n(self, tension_n: float | None) -> None:
        """Measure this tension from now on (None: the plant's again)."""
        self._tension_override_n = tension_n

    def fail_next(self, count: int) -> None:
        """The next ``count`` transfers fail with EIO (a loose wire)."""
        self._failures_left = count

    # --- the device ------------------------------------------------------------------------------
    def _period_s(self) -> float:
        return 1.0 / DATA_RATES_SPS[(self._registers[REG_CONFIG] >> 5) & 0b111]

    def _input_volts(self) -> float:
        mux = (self._registers[REG_CONFIG] >> 12) & 0b111
        if mux != 0:
            return 0.0  # only AIN0−AIN1 is wired to the amplifier
        tension = self._tension_override_n
        if tension is None:
            sample = self._plant.tension()
            tension = sample.tension_n if sample is not None else 0.0
        return self.offset_v + self.volts_per_newton * tension

    def _convert(self) -> None:
        full_scale = FULL_SCALE_V[(self._registers[REG_CONFIG] >> 9) & 0b111]
        code = math.floor(self._input_volts() / full_scale * 32768.0 + 0.5)
        code = min(max(code, -32768), 32767)
        self._registers[REG_CONVERSION] = code & 0xFFFF

    def _update(self, now: float) -> None:
        """Complete the conversions due by ``now``."""
        config = self._registers[REG_CONFIG]
        if config & MODE_SINGLE_SHOT:
            if now >= self._next_conversion_s:
                self._convert()
                self._next_conversion_s = math.inf
                self._registers[REG_CONFIG] = config | OS_BIT  # conversion done
            return
        if now >= self._next_conversion_s:
            self._convert()
            periods = math.floor((now - self._next_conversion_s) / self._period_s()) + 1
            self._next_conversion_s += periods * self._period_s()

    def _check(self, failure: int) -> None:
        if self._failures_left > 0:
            self._failures_left -= 1
            raise OSError(failure, f"I2C transfer to {self.address:#x} failed: {errno.errorcode[failure]}")

    def write_register(self, register: int, data: Sequence[int]) -> None:
        """An I²C write: pointer byte ``register`` then ``data`` (MSB first)."""
        with self._lock:
            self._check(errno.EIO)
            if register not in self._registers:
                raise OSError(errno.EIO, f"ADS1115 has no register {register:#x}")
            if len(data) != 2 or register == REG_CONVERSION:
                return  # a pointer-only write, or the read-only conversion register: nothing stored
            word = (data[0] << 8) | data[1]
            now = self._time_source()
            if register != REG_CONFIG:
                self._registers[register] = word
                return
            if word & MODE_SINGLE_SHOT:
                self._registers[REG_CONFIG] = word & ~OS_BIT if word & OS_BIT else word | OS_BIT
                if word & OS_BIT:
                    self._next_conversion_s = now + self._period_s()
                else:
                    self._next_conversion_s = math.inf
            else:
                # Continuous: the first result is ready one period after the write.
                self._registers[REG_CONFIG] = word | OS_BIT
                self._next_conversion_s = now + self._period_s()

    def read_register(self, register: int, length: int) -> list[int]:
        """An I²C read of ``length`` bytes from ``register`` (the pointer moves there first)."""
        with self._lock:
            self._check(errno.EIO)
            if register not in self._registers:
                raise OSError(errno.EIO, f"ADS1115 has no register {register:#x}")
            self._update(self._time_source())
            self.reads += 1
            word = self._registers[register]
            data = [(word >> 8) & 0xFF, word & 0xFF]
            # Past the register the device keeps clocking out the same two bytes.
            return [data[i % 2] for i in range(length)]


class FakeSMBus:
    """An I²C bus with simulated devices, shaped like ``smbus2.SMBus``."""

    def __init__(self, *devices: ADS1115Peer) -> None:
        self._devices = {device.address: device for device in devices}
        self.closed = False

    def _device(self, i2c_addr: int) -> ADS1115Peer:
        if self.closed:
            raise OSError(errno.EBADF, "I2C bus is closed")
        device = self._devices.get(i2c_addr)
        if device is None:
            raise OSError(errno.EREMOTEIO, f"Remote I/O error: nothing at {i2c_addr:#x}")
        return device

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int,
                            force: bool | None = None) -> list[int]:
        if not 1 <= length <= 32:
            raise ValueError("Desired block length over 32 bytes")  # smbus2's own check
        return self._device(i2c_addr).read_register(register, length)

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: Sequence[int],
                             force: bool | None = None) -> None:
        if len(data) > 32:
            raise ValueError("Data length cannot exceed 32 bytes")
        self._device(i2c_addr).write_register(register, list(data))

    def read_word_data(self, i2c_addr: int, register: int, force: bool | None = None) -> int:
        """SMBus word read: little-endian, so the ADS1115's MSB arrives as the low byte."""
        msb, lsb = self._device(i2c_addr).read_register(register, 2)
        return (lsb << 8) | msb

    def write_word_data(self, i2c_addr: int, register: int, value: int, force: bool | None = None) -> None:
        """SMBus word write: little-endian on the wire."""
        self._device(i2c_addr).write_register(register, [value & 0xFF, (value >> 8) & 0xFF])

    def close(self) -> None:
        self.closed = True

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
