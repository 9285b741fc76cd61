"""ADS1115 load cell: register encoding by hand, the reader against the simulated ADC, fuzzing."""

from __future__ import annotations

import inspect
import math
import time
from collections.abc import Callable, Iterator

import pytest
import smbus2
from hypothesis import given
from hypothesis import strategies as st

from bowden.errors import HardwareError, MalformedFrameError, ParameterError
from bowden.hardware.ads1115 import (
    DEFAULT_CONFIG,
    MODE_SINGLE_SHOT,
    OS_BIT,
    REG_CONFIG,
    REG_CONVERSION,
    ADS1115Config,
    ADS1115LoadCell,
    LoadCellCalibration,
    conversion_to_volts,
    encode_config,
    register_bytes,
    word_from_bytes,
)
from bowden.hardware.protocols import TensionSensor
from bowden.sim.peers import ADS1115Peer, FakeSMBus, WallTimePlant

CALIBRATION = LoadCellCalibration(offset_v=0.05, gain_n_per_v=100.0)  # the peer's amplifier, inverted


def wait_for(condition: Callable[[], bool], timeout_s: float = 5.0) -> None:
    end = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > end:
            raise AssertionError("condition not met within the timeout")
        time.sleep(0.002)


@pytest.fixture
def adc(wall_plant: WallTimePlant) -> ADS1115Peer:
    return ADS1115Peer(wall_plant, offset_v=0.05, volts_per_newton=0.01)


@pytest.fixture
def load_cell(adc: ADS1115Peer) -> Iterator[ADS1115LoadCell]:
    with FakeSMBus(adc) as bus, ADS1115LoadCell(bus, calibration=CALIBRATION) as cell:
        yield cell


def test_config_words_by_hand() -> None:
    # The power-on value 0x8583: OS, AIN0−AIN1, ±2.048 V (PGA 2), single shot, 128 SPS (DR 4), no comparator.
    assert encode_config(mux=0, pga=2, continuous=False, data_rate=4, start=True) == DEFAULT_CONFIG == 0x8583
    # Continuous, ±4.096 V, 860 SPS: 1 << 9 | 7 << 5 | 0b11 = 0x02E3.
    assert encode_config(mux=0, pga=1, continuous=True, data_rate=7) == 0x02E3
    assert register_bytes(0x02E3) == [0x02, 0xE3]


def test_conversion_codes_by_hand() -> None:
    assert conversion_to_volts([0x7F, 0xFF], 4.096) == pytest.approx(32767 * 4.096 / 32768)
    assert conversion_to_volts([0x80, 0x00], 4.096) == -4.096
    assert conversion_to_volts([0xFF, 0xFF], 4.096) == pytest.approx(-0.000125)
    assert conversion_to_volts([0x00, 0x01], 0.256) == pytest.approx(7.8125e-6)


@given(st.lists(st.integers(-300, 300), max_size=4))
def test_random_register_bytes_never_crash_the_parser(data: list[int]) -> None:
    try:
        volts = conversion_to_volts(data, 4.096)
    except MalformedFrameError:
        assert len(data) != 2 or not all(0 <= b <= 255 for b in data)
        return
    assert -4.096 <= volts < 4.096


@given(st.integers(0, 0xFFFF))
def test_register_bytes_round_trip(word: int) -> None:
    assert word_from_bytes(register_bytes(word)) == word


def test_two_point_calibration() -> None:
    calibration = LoadCellCalibration.from_two_points(volts_1=0.1, tension_1_n=0.0,
                                                      volts_2=0.6, tension_2_n=50.0)
    assert calibration.gain_n_per_v == pytest.approx(100.0)
    assert calibration.offset_v == pytest.approx(0.1)
    assert calibration.tension_n(0.35) == pytest.approx(25.0)
    with pytest.raises(ParameterError, match="different voltages"):
        LoadCellCalibration.from_two_points(volts_1=0.1, tension_1_n=0.0, volts_2=0.1, tension_2_n=5.0)
    with pytest.raises(ParameterError, match="gain_n_per_v"):
        LoadCellCalibration(gain_n_per_v=0.0)


def test_reader_measures_the_tension(load_cell: ADS1115LoadCell, adc: ADS1115Peer) -> None:
    assert isinstance(load_cell, TensionSensor)
    adc.override_tension_n(50.0)
    wait_for(lambda: (s := load_cell.read()) is not None and abs(s.tension_n - 50.0) < 0.1)
    sample = load_cell.read()
    assert sample is not None
    # 0.55 V on ±4.096 V: one code is 125 µV = 12.5 mN after the 100 N/V gain.
    assert sample.tension_n == pytest.approx(50.0, abs=0.0125)
    assert load_cell.counters.io_errors == 0


def test_reader_follows_the_plant(load_cell: ADS1115LoadCell, wall_plant: WallTimePlant) -> None:
    wait_for(lambda: load_cell.read() is not None)
    truth = wall_plant.tension()
    sample = load_cell.read()
    assert truth is not None and sample is not None
    assert sample.tension_n == pytest.approx(truth.tension_n, abs=0.5)


def test_io_errors_are_counted_and_survived(adc: ADS1115Peer) -> None:
    # Fewer failed reads in a row than make a lost sensor, whatever time they span: with the default
    # bound (3 reads over 20 ms) a reader starved beside busy processes spanned 36 ms and was lost.
    config = ADS1115Config(max_consecutive_errors=4)
    with FakeSMBus(adc) as bus, ADS1115LoadCell(bus, config, calibration=CALIBRATION) as load_cell:
        wait_for(lambda: load_cell.counters.samples > 0)
        adc.fail_next(3)
        wait_for(lambda: load_cell.counters.io_errors == 3)
        before = load_cell.counters.samples
        wait_for(lambda: load_cell.counters.samples > before)
        assert load_cell.failure is None


def test_reader_gives_up_after_too_many_errors(adc: ADS1115Peer) -> None:
    config = ADS1115Config(max_consecutive_errors=5, lost_after_s=0.0)
    with FakeSMBus(adc) as bus, ADS1115LoadCell(bus, config) as cell:
        adc.fail_next(1000)
        wait_for(lambda: cell.failure is not None)
        assert "5 I²C errors in a row over" in str(cell.failure)


def test_failed_reads_must_also_span_the_time_limit(adc: ADS1115Peer) -> None:
    """A few failed reads in a row (a glitch) are not a lost sensor; failing on for 20 ms is."""
    with FakeSMBus(adc) as bus, ADS1115LoadCell(bus, ADS1115Config(data_rate=7)) as cell:
        adc.fail_next(5)  # 5 failed reads at 860 SPS: under 6 ms
        wait_for(lambda: cell.counters.io_errors == 5)
        before = cell.counters.samples
        wait_for(lambda: cell.counters.samples > before)
        assert cell.failure is None
        adc.fail_next(10**6)
        wait_for(lambda: cell.failure is not None)
        spanned_ms = int(str(cell.failure).split(" over ")[1].split(" ms")[0])
        assert spanned_ms >= 20 and cell.counters.io_errors - 5 >= 3


def test_tare_zeroes_the_offset(load_cell: ADS1115LoadCell, adc: ADS1115Peer) -> None:
    adc.override_tension_n(0.0)
    wait_for(lambda: load_cell.read() is not None)
    calibration = load_cell.tare(0.05)
    assert calibration.offset_v == pytest.approx(0.05, abs=2e-4)
    assert calibration.gain_n_per_v == 100.0


def test_missing_device_is_a_clear_error(adc: ADS1115Peer) -> None:
    with FakeSMBus(adc) as bus, pytest.raises(HardwareError, match="0x49 does not answer"):
        ADS1115LoadCell(bus, ADS1115Config(address=0x49)).start()


def test_close_powers_the_adc_down(adc: ADS1115Peer) -> None:
    with FakeSMBus(adc) as bus:
        with ADS1115LoadCell(bus):
            pass
        assert word_from_bytes(bus.read_i2c_block_data(0x48, REG_CONFIG, 2)) & MODE_SINGLE_SHOT


class ManualTime:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_continuous_conversions_change_once_per_period(wall_plant: WallTimePlant) -> None:
    clock = ManualTime()
    adc = ADS1115Peer(wall_plant, offset_v=0.0, volts_per_newton=0.01, time_source=clock)
    bus = FakeSMBus(adc)
    adc.override_tension_n(10.0)
    bus.write_i2c_block_data(0x48, REG_CONFIG, register_bytes(encode_config(mux=0, pga=1, continuous=True,
                                                                              data_rate=4)))  # 128 SPS
    assert bus.read_i2c_block_data(0x48, REG_CONVERSION, 2) == [0, 0]  # nothing converted yet
    clock.now = 1.0 / 128
    assert conversion_to_volts(bus.read_i2c_block_data(0x48, REG_CONVERSION, 2), 4.096) == pytest.approx(
        0.1, abs=1.25e-4)
    adc.override_tension_n(20.0)
    clock.now = 1.5 / 128  # mid-conversion: the register holds the last result
    assert conversion_to_volts(bus.read_i2c_block_data(0x48, REG_CONVERSION, 2), 4.096) == pytest.approx(
        0.1, abs=1.25e-4)
    clock.now = 2.0 / 128
    assert conversion_to_volts(bus.read_i2c_block_data(0x48, REG_CONVERSION, 2), 4.096) == pytest.approx(
        0.2, abs=1.25e-4)


def test_single_shot_and_saturation(wall_plant: WallTimePlant) -> None:
    clock = ManualTime()
    adc = ADS1115Peer(wall_plant, offset_v=0.0, volts_per_newton=1.0, time_source=clock)
    bus = FakeSMBus(adc)
    adc.override_tension_n(10.0)  # 10 V: beyond any full scale
    start = encode_config(mux=0, pga=5, continuous=False, data_rate=7, start=True)
    bus.write_i2c_block_data(0x48, REG_CONFIG, register_bytes(start))
    assert not word_from_bytes(bus.read_i2c_block_data(0x48, REG_CONFIG, 2)) & OS_BIT  # converting
    clock.now = 1.0 / 860
    assert word_from_bytes(bus.read_i2c_block_data(0x48, REG_CONFIG, 2)) & OS_BIT  # done
    assert bus.read_i2c_block_data(0x48, REG_CONVERSION, 2) == [0x7F, 0xFF]  # saturated at +FS
    # SMBus word transfers are little-endian: the ADS1115's bytes come back swapped.
    assert bus.read_word_data(0x48, REG_CONVERSION) == 0xFF7F


def test_fake_bus_has_smbus2_signatures() -> None:
    for name in ("read_i2c_block_data", "write_i2c_block_data", "read_word_data", "write_word_data", "close"):
        real = list(inspect.signature(getattr(smbus2.SMBus, name)).parameters)
        fake = list(inspect.signature(getattr(FakeSMBus, name)).parameters)
        assert fake == real, name


def test_config_validation() -> None:
    with pytest.raises(ParameterError, match="address"):
        ADS1115Config(address=0x50)
    with pytest.raises(ParameterError, match="pga"):
        ADS1115Config(pga=9)
    assert math.isclose(ADS1115Config(pga=2).full_scale_v, 2.048)
