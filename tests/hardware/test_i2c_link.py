"""I²C across a socket: the ADS1115 driver reads the simulated ADC as over its own bus."""

from __future__ import annotations

import errno
import time
from pathlib import Path

import pytest

from bowden.hardware.ads1115 import ADS1115Config, ADS1115LoadCell, LoadCellCalibration
from bowden.sim.link.i2c import I2CServer, RemoteSMBus
from bowden.sim.peers import ADS1115Peer, FakeSMBus, WallTimePlant


def test_the_driver_reads_tension_through_the_link(wall_plant: WallTimePlant, tmp_path: Path) -> None:
    adc = ADS1115Peer(wall_plant, offset_v=0.05, volts_per_newton=0.01)
    adc.override_tension_n(42.0)
    calibration = LoadCellCalibration(offset_v=0.05, gain_n_per_v=100.0)
    with I2CServer(FakeSMBus(adc), tmp_path / "i2c.sock"), RemoteSMBus(tmp_path / "i2c.sock") as bus, \
            ADS1115LoadCell(bus, ADS1115Config(data_rate=6), calibration=calibration) as cell:
        deadline = time.monotonic() + 5.0
        while (sample := cell.read()) is None and time.monotonic() < deadline:
            time.sleep(0.005)
        assert sample is not None and sample.tension_n == pytest.approx(42.0, abs=0.01)


def test_errors_come_back_with_their_errno(wall_plant: WallTimePlant, tmp_path: Path) -> None:
    adc = ADS1115Peer(wall_plant)
    server = I2CServer(FakeSMBus(adc), tmp_path / "i2c.sock").start()
    try:
        with RemoteSMBus(tmp_path / "i2c.sock") as bus:
            with pytest.raises(OSError) as nobody:
                bus.read_i2c_block_data(0x49, 0, 2)  # no device at this address
            assert nobody.value.errno == errno.EREMOTEIO
            adc.fail_next(1)
            with pytest.raises(OSError) as loose:
                bus.read_i2c_block_data(0x48, 0, 2)
            assert loose.value.errno == errno.EIO
            assert len(bus.read_i2c_block_data(0x48, 1, 2)) == 2  # and then it works again
            server.silent = True  # unplugged: no answer at all
            with pytest.raises(OSError) as silent:
                bus.read_i2c_block_data(0x48, 1, 2)
            assert silent.value.errno == errno.ETIMEDOUT
    finally:
        server.close()
    assert not (tmp_path / "i2c.sock").exists()
