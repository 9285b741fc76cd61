import edfio
import numpy as np
import pytest

from bowden.analysis import EmgCheckParameters, EmgSignal, emg_align, emg_check, read_emg_csv, read_emg_edf
from bowden.contracts import MUSCLES
from bowden.errors import ParameterError, RecordingError

from .conftest import RATE_HZ, emg_noise


def _emg(seconds: float = 2.0, seed: int = 0) -> EmgSignal:
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE_HZ)
    data = np.column_stack([50e-6 * emg_noise(n, rng) for _ in MUSCLES])
    return EmgSignal(values=data, rate_hz=RATE_HZ, channels=MUSCLES)


@pytest.mark.parametrize(("suffix", "signal_class"), [(".edf", edfio.EdfSignal), (".bdf", edfio.BdfSignal)])
def test_edf_and_bdf_files_read_back_in_volts(tmp_path, suffix, signal_class):
    emg = _emg()
    labels = [f"EMG{i}" for i in range(len(MUSCLES))]
    signals = [
        signal_class(
            emg.values[:, i] * 1e6,
            RATE_HZ,
            label=labels[i],
            physical_dimension="uV",
            physical_range=(-1000.0, 1000.0),
        )
        for i in range(len(MUSCLES))
    ]
    path = tmp_path / f"emg{suffix}"
    edfio.Edf(signals).write(path) if suffix == ".edf" else edfio.Bdf(signals).write(path)
    read = read_emg_edf(path, channel_map=dict(zip(labels, MUSCLES, strict=True)))
    assert read.channels == MUSCLES
    assert read.rate_hz == RATE_HZ
    resolution = 2000e-6 / (2**16 if suffix == ".edf" else 2**24)  # one digital step, V
    assert np.max(np.abs(read.values - emg.values)) <= resolution
    emg_check(read)
    with pytest.raises(RecordingError, match="lacks channel"):
        read_emg_edf(path, channels=["deltoid"])


def test_edf_with_unknown_unit_or_mixed_rates_is_refused(tmp_path):
    path = tmp_path / "mixed.edf"
    edfio.Edf(
        [
            edfio.EdfSignal(
                np.zeros(2000), 2000.0, label="a", physical_dimension="uV", physical_range=(-1, 1)
            ),
            edfio.EdfSignal(
                np.zeros(1000), 1000.0, label="b", physical_dimension="uV", physical_range=(-1, 1)
            ),
            edfio.EdfSignal(
                np.zeros(2000), 2000.0, label="c", physical_dimension="degC", physical_range=(-1, 1)
            ),
        ]
    ).write(path)
    with pytest.raises(RecordingError, match="different sampling rates"):
        read_emg_edf(path, channels=["a", "b"])
    with pytest.raises(RecordingError, match="physical dimension 'degC'"):
        read_emg_edf(path, channels=["c"])
    with pytest.raises(RecordingError, match="does not exist"):
        read_emg_edf(tmp_path / "nothing.edf")


def test_csv_reader_converts_units(tmp_path):
    emg = _emg()
    frame = emg.to_frame()
    frame[list(MUSCLES)] *= 1e6
    frame.to_csv(tmp_path / "emg.csv", index=False)
    read = read_emg_csv(tmp_path / "emg.csv", volts_per_unit=1e-6)
    assert read.values == pytest.approx(emg.values, rel=1e-9, abs=1e-15)
    assert read.rate_hz == pytest.approx(RATE_HZ, rel=1e-9)


def test_check_names_each_bad_channel():
    emg = _emg()
    values = np.array(emg.values)
    values[:, 1] = 0.0  # flat
    values[:, 2] = np.clip(values[:, 2], -20e-6, 20e-6)  # clipped
    values[100:1200, 3] = values[100, 3]  # stuck for 1100 samples = 1.1 s at 1 kHz
    values[5, 4] = np.nan  # missing data
    bad = EmgSignal(values=values[:, 1:], rate_hz=1000.0, channels=MUSCLES[1:])  # channel 0 missing
    with pytest.raises(RecordingError) as excinfo:
        emg_check(bad)
    message = str(excinfo.value)
    assert "sampling rate is 1000 Hz, expected 2000 Hz" in message
    assert f"channel {MUSCLES[0]!r} is missing" in message
    assert f"channel {MUSCLES[1]!r} is flat" in message
    assert f"channel {MUSCLES[2]!r} is clipped" in message
    assert f"channel {MUSCLES[3]!r} is flat for 1.100 s" in message
    assert f"channel {MUSCLES[4]!r} is missing data" in message
    assert f"channel {MUSCLES[5]!r} is" not in message
    emg_check(_emg())  # a good recording passes
    with pytest.raises(ParameterError, match="expected_rate_hz"):
        EmgCheckParameters(expected_rate_hz=-1.0)


def test_align_by_sync_pulses_corrects_offset_and_drift():
    rate_emg = 2000.0 * (1.0 + 50e-6)  # the EMG clock runs 50 ppm fast
    n = int(60 * rate_emg)
    pulses_controller = np.array([5.0, 17.0, 31.0, 55.0])  # logged by the controller
    offset = 3.25  # controller time of the EMG's first sample
    sync = np.zeros(n)
    t_emg_true = offset + np.arange(n) / 2000.0  # true controller time of each EMG sample
    for p in pulses_controller:
        sync[(t_emg_true >= p) & (t_emg_true < p + 0.05)] = 5.0
    emg = EmgSignal(
        values=np.column_stack([np.zeros(n), sync]), rate_hz=rate_emg, channels=("biceps", "sync")
    )
    aligned = emg_align(emg, sync_channel="sync", controller_times_s=pulses_controller)
    assert aligned.channels == ("biceps",)
    assert aligned.start_s == pytest.approx(offset, abs=1e-3)
    assert aligned.rate_hz == pytest.approx(2000.0, rel=1e-6)
    assert emg_align(emg, offset_s=1.5).start_s == 1.5
    with pytest.raises(RecordingError, match="4 rising edges but the controller logged 3"):
        emg_align(emg, sync_channel="sync", controller_times_s=pulses_controller[:3])
    with pytest.raises(ParameterError, match="either offset_s"):
        emg_align(emg, offset_s=1.0, sync_channel="sync", controller_times_s=pulses_controller)
