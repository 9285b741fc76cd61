"""EDF+/BDF+ writing of stored EMG codes: bit for bit, the right format, refusals."""

from __future__ import annotations

from pathlib import Path

import edfio
import numpy as np
import pytest

from bowden.share.emg_codes import file_codes, stored_values
from bowden.share.emg_file import BDF_RANGE, emg_extension, file_rate_hz, record_plan, write_emg_file
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
    assert [c.muscle for c in written.channels] == ["biceps", "posterior_deltoid"]
    np.testing.assert_array_equal(back.signals[0].digital, codes)
    np.testing.assert_array_equal(back.signals[1].digital, codes[::-1])
    assert back.signals[0].sampling_frequency == 2048.0


def test_16_bit_codes_go_to_edf_and_floats_to_bdf() -> None:
    assert emg_extension({"biceps": _channel(np.array([1, -2], dtype=np.int16))}) == ".edf"
    assert emg_extension({"biceps": _channel(np.array([0.5, 1.5], dtype=np.float32))}) == ".bdf"


def test_records_hold_whole_samples_and_the_rate_is_the_nominal_one() -> None:
    # 23001 samples at 2 kHz (a simulated trial, 3·11·17·41): 1353 samples per record, the most ≤ 1 s.
    assert record_plan(23001, 2000.0) == (1353, pytest.approx(1353 / 2000.0))
    assert record_plan(4000, 2000.0) == (2000, 1.0)
    # At 2048 Hz a record's duration fits 8 characters only for multiples of 32 samples (1/64 s =
    # 0.015625): a prime number of samples has none dividing it, so 1-s records, the last one padded.
    assert record_plan(6151, 2048.0) == (2048, 1.0)
    assert file_rate_hz(1999.9999999999982) == 2000.0  # 1 / the median step of a stored trial
    assert file_rate_hz(2000.5) == 2000.5  # 4001 samples in 2 s records
    assert file_rate_hz(2048.0011) == 2048.0  # an import's rate on the host clock: the nominal one


def test_a_prime_number_of_samples_is_padded_and_the_padding_marked(tmp_path: Path) -> None:
    import mne

    codes = np.random.default_rng(5).integers(-30000, 30000, size=6151, dtype=np.int16)  # prime
    written = write_emg_file(tmp_path / "p_emg.edf", {"biceps": _channel(codes)}, start=None)
    assert (written.samples, written.padding, written.duration_s) == (6151, 2041, 6151 / 2048)
    back = edfio.read_edf(tmp_path / "p_emg.edf")
    np.testing.assert_array_equal(back.signals[0].digital[:6151], codes)  # the stored codes, bit for bit
    (skip,) = back.annotations
    assert (skip.onset, skip.duration, skip.text) == (6151 / 2048, 2041 / 2048, "BAD_ACQ_SKIP")
    raw = mne.io.read_raw_edf(tmp_path / "p_emg.edf", verbose="ERROR")
    assert raw.n_times == 8192  # MNE reads whole records, the padding too ...
    kept = raw.get_data(reject_by_annotation="omit")
    assert kept.shape == (1, 6151)  # ... and leaves out what the annotation marks
    np.testing.assert_allclose(kept[0], codes * 3.1e-8, rtol=0, atol=0.5 * 3.1e-8)


def test_float32_counts_of_an_amplifier_go_to_bdf_bit_for_bit(tmp_path: Path) -> None:
    # TMSi SAGA's LSL stream: 24-bit counts times the unit gain, as float32 microvolts.
    rng = np.random.default_rng(7)
    counts = np.rint(rng.normal(0.0, 3000.0, size=4096) * rng.uniform(0.2, 3.0, size=4096)).astype(np.int64)
    counts[:2] = -(2**23), 2**23 - 1  # the amplifier's full range too
    gain_uv = np.float32(0.01788139343)  # 150 mV over 2^24 counts
    values = (counts * gain_uv).astype(np.float32)
    channel = _channel(values, gain_v=1e-6)
    codes = file_codes(values, BDF_RANGE)
    assert codes.exact
    np.testing.assert_array_equal(stored_values(codes, values.dtype).view(np.uint32), values.view(np.uint32))
    written = write_emg_file(tmp_path / "f_emg.bdf", {"biceps": channel}, start=None)
    (described,) = written.channels
    assert (described.stored_format, described.exact) == ("float32", True)
    digital = edfio.read_bdf(tmp_path / "f_emg.bdf").signals[0].digital
    back = (digital.astype(np.float64) * described.code_step).astype(np.float32)
    np.testing.assert_array_equal(back.view(np.uint32), values.view(np.uint32))


def test_floats_off_any_24_bit_lattice_are_quantised_and_flagged() -> None:
    values = np.random.default_rng(9).normal(0.0, 50.0, size=1000).astype(np.float32)  # filtered floats
    codes = file_codes(values, BDF_RANGE)
    assert not codes.exact
    assert 0.0 < codes.max_error <= 0.5 * codes.step * (1 + 1e-9)
    wide = np.array([2**30 + 1, -(2**30), 7], dtype=np.int64)  # 32-bit counts with no common factor
    assert not file_codes(wide, BDF_RANGE).exact
    shifted = np.array([5 << 8, -(3 << 8), (2**23 - 1) << 8], dtype=np.int32)  # 24 bits shifted into 32
    exact = file_codes(shifted, BDF_RANGE)
    assert exact.exact and exact.step == 256.0
