"""EDF+/BDF+ writing of stored EMG codes: bit for bit, the right format, refusals."""

from __future__ import annotations

from pathlib import Path

import edfio
import numpy as np
import pytest

from bowden.errors import StoreError
from bowden.share.emg_file import _record_duration, emg_extension, file_rate_hz, write_emg_file
from bowden.store.emg_chunks import StoredEmgChannel


def _channel(codes: np.ndarray, gain_v: float = 3.1e-8, offset_v: float = 0.0) -> StoredEmgChannel:
    return StoredEmgChannel(codes, gain_v, offset_v, rate_hz=2048.0, start_time_s=0.25)


def test_24_bit_codes_go_to_bdf_bit_for_bit(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    codes = rng.integers(-(2**23), 2**23, size=2048 * 3 + 32, dtype=np.int32)  # an imported BDF's codes
    channels = {"biceps": _channel(codes, 1.7e-9, 2.5e-6), "posterior_deltoid": _channel(codes[::-1].copy())}
    assert emg_extension(channels) == ".bdf"
    written = write_emg_file(tmp_path / "x_emg.bdf", channels, start=None)
    back = edfio.read_bdf(tmp_path / "x_emg.bdf")
    assert [s.label for s in back.signals] == ["biceps", "post_deltoid"]  # 16 characters at most
    assert [c.muscle for c in written] == ["biceps", "posterior_deltoid"]
    np.testing.assert_array_equal(back.signals[0].digital, codes)
    np.testing.assert_array_equal(back.signals[1].digital, codes[::-1])
    assert back.signals[0].sampling_frequency == 2048.0


def test_16_bit_codes_go_to_edf_and_floats_are_refused() -> None:
    assert emg_extension({"biceps": _channel(np.array([1, -2], dtype=np.int16))}) == ".edf"
    with pytest.raises(StoreError, match=r"'biceps'.*float32.*without rounding"):
        emg_extension({"biceps": _channel(np.array([0.5, 1.5], dtype=np.float32))})


def test_records_hold_whole_samples_and_the_rate_is_the_nominal_one() -> None:
    # 23001 samples at 2 kHz (a simulated trial, 3·11·17·41): 1353 samples per record, the most ≤ 1 s.
    assert _record_duration(23001, 2000.0) == pytest.approx(1353 / 2000.0)
    assert _record_duration(4000, 2000.0) == 1.0
    assert file_rate_hz(1999.9999999999982) == 2000.0  # 1 / the median step of a stored trial
    assert file_rate_hz(2000.5) == 2000.5
    # At 2048 Hz a record's duration fits 8 characters only for multiples of 32 samples (1/64 s =
    # 0.015625): a prime number of samples has none, and is refused rather than padded or cut.
    with pytest.raises(StoreError, match="6151 samples at 2048"):
        _record_duration(6151, 2048.0)
