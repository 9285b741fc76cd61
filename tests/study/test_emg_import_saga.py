"""`bowden emg import` of files shaped like a TMSi SAGA's exports (issue 27, items 2, 4, 5 and 8).

The SAGA's TRIGGER port is negative logic (a bit reads 1 while nothing drives it, 0 while a trigger
does; TMSi knowledge base, "How can I send triggers to SAGA via USB ports?") and 16 bits wide, shared
with whatever else is wired to it; its files also carry digital channels (TRIGGERS, STATUS, COUNTER)
with no voltage unit. A BDF keeps 24-bit codes, which the store must keep code for code.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import edfio
import numpy as np
import pytest

from bowden.analysis.emg.channels import SAGA_CHANNELS
from bowden.cli import main
from bowden.store import emg_chunks
from bowden.store.study_store import StudyStore
from bowden.study.emg.importer import ImportOptions, import_emg

from .emg_session import TRIGGER, Session, simulate_session, write_saga_file

MAP = ["--channels", "saga"]


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Session:
    # A short session (three trials within 70 s) keeps the files small.
    return simulate_session(tmp_path_factory.mktemp("saga"), zeros_s=(100.0, 131.0, 170.0), offset_s=2.2)


@pytest.fixture
def store(session: Session, tmp_path: Path) -> Path:
    copy = tmp_path / "study.db"
    shutil.copyfile(session.store, copy)
    return copy


def _refused(store: Path, path: Path, *extra: str, capsys: pytest.CaptureFixture[str]) -> str:
    code = main(["emg", "import", str(store), str(path), *extra])
    err = capsys.readouterr().err.strip()
    assert code == 1 and err.startswith("bowden: error: ") and "\n" not in err, err
    with StudyStore(store) as opened:
        assert opened.trials_with_emg() == []
    return err


def _first_samples(session: Session, store: Path) -> dict[int, int]:
    """Per trial, which recording sample its first stored sample is (by value: the truth's span)."""
    return {trial.trial_id: int(session.trial_span(trial)[0]) for trial in session.trials}


def test_a_negative_logic_trigger_line_is_read_from_its_baseline(session, store, tmp_path, capsys):
    path = tmp_path / "saga.edf"
    write_saga_file(session, path, bowden_bit=None)  # TRIGGERS idles at 1, 0 during each trial
    args = ["emg", "import", str(store), str(path), "--trigger-channel", TRIGGER, *MAP]
    assert main(args) == 0
    assert "imported EMG of trial(s) 1, 2, 3 (by trigger: 6 sync events" in capsys.readouterr().out


def test_positive_polarity_on_a_negative_logic_line_says_which_flag_to_give(session, store, tmp_path, capsys):
    path = tmp_path / "saga.edf"
    write_saga_file(session, path, bowden_bit=None)
    err = _refused(
        store, path, "--trigger-channel", TRIGGER, *MAP, "--trigger-polarity", "high", capsys=capsys
    )
    assert err.startswith("bowden: error: saga.edf: ") and "--trigger-polarity low" in err


def test_one_bit_of_a_trigger_word_shared_with_another_device(session, store, tmp_path, capsys):
    # bowden's line on bit 1, a stimulus PC pulsing bit 8 twelve times; BDF: the word is scaled into
    # 24-bit codes (0..65535 → not whole numbers once decoded), as TMSi's converter lays it out.
    path = tmp_path / "shared.bdf"
    write_saga_file(session, path, bowden_bit=1, other_bit=8, other_pulses=12)
    base = ["emg", "import", str(store), str(path), "--trigger-channel", TRIGGER, *MAP]
    err = _refused(store, path, *base[3:], capsys=capsys)
    assert "pulse(s) too many" in err and "--trigger-bit N" in err
    assert err.startswith("bowden: error: shared.bdf")
    assert main([*base, "--trigger-bit", "1"]) == 0
    out = capsys.readouterr().out
    assert "imported EMG of trial(s) 1, 2, 3" in out
    drift = re.search(r"drift ([+-]\d+\.\d) ppm", out)
    # Hard edges on a 0.5 ms grid over 70 s: the +80 ppm within a few ppm.
    assert drift is not None and abs(float(drift.group(1)) - 80.0) < 5.0


def test_a_trigger_bit_of_a_channel_without_integer_values_is_refused(session, store, tmp_path, capsys):
    path = tmp_path / "saga.edf"
    write_saga_file(session, path, bowden_bit=None)
    # Scale the line to 0..0.5 V: no longer integers, so it has no bits.
    recording = edfio.read_edf(path)
    signal = recording.signals[[s.label for s in recording.signals].index(TRIGGER)]
    signal.update_data(signal.data * 0.37)
    recording.write(path)
    err = _refused(store, path, "--trigger-channel", TRIGGER, *MAP, "--trigger-bit", "0", capsys=capsys)
    assert "does not hold integer values" in err and "leave out --trigger-bit" in err
    err = _refused(store, path, "--trigger-channel", TRIGGER, *MAP, "--trigger-bit", "40", capsys=capsys)
    assert "--trigger-bit must be 0–31, got 40" in err


def test_a_saga_file_without_channels_says_the_labels_are_unknown_and_how_to_map_them(
    session, store, tmp_path, capsys
):
    path = tmp_path / "saga.bdf"
    write_saga_file(session, path, bowden_bit=None)
    err = _refused(store, path, "--trigger-channel", TRIGGER, capsys=capsys)
    assert err.startswith("bowden: error: saga.bdf: unknown channel labels UNI1, ")
    assert "give --channels MAP" in err and "'saga'" in err and "STATUS" not in err


def test_errors_of_several_files_name_the_file_and_the_flags(session, store, tmp_path, capsys):
    good = tmp_path / "good.edf"
    write_saga_file(session, good, bowden_bit=None)
    err = _refused(store, good, "--trigger-channel", TRIGGER, *MAP, "--rate", "-5", capsys=capsys)
    assert "--rate must be a positive rate in Hz, got -5" in err and "expected_rate_hz" not in err
    err = _refused(store, good, "--trigger-channel", TRIGGER, *MAP, "--max-drift-ppm", "0", capsys=capsys)
    assert "--max-drift-ppm must be positive" in err and "drift_tolerance_ppm" not in err
    err = _refused(store, good, "--trigger-channel", TRIGGER, *MAP, "--rate", "1000", capsys=capsys)
    assert err.startswith("bowden: error: good.edf, trial 1: sampling rate is ")
    assert "--rate" in err and "expected_rate_hz" not in err
    # Of two recordings the second fails: its name, not the first's, leads the message.
    bad = tmp_path / "second.edf"
    write_saga_file(session, bad, bowden_bit=None)
    code = main(["emg", "import", str(store), str(good), str(bad), *MAP])
    err = capsys.readouterr().err.strip()
    assert code == 1 and err == (
        "bowden: error: good.edf: give --trigger-channel NAME (the channel recording bowden's trigger)"
    )


def test_trigger_flags_without_a_trigger_channel_are_refused_not_ignored(session, store, tmp_path, capsys):
    # An XDF file without --trigger-channel is synchronised by markers, which no trigger flag reads.
    path = tmp_path / "markers.xdf"
    path.write_bytes(b"")  # refused before any file is read
    err = _refused(store, path, "--trigger-bit", "3", capsys=capsys)
    assert err == ("bowden: error: --trigger-bit reads the trigger channel: give --trigger-channel NAME too "
                   "(without it an XDF recording is synchronised by bowden's LSL markers)")
    err = _refused(store, path, "--trigger-polarity", "low", "--trigger-bit", "0", capsys=capsys)
    assert "--trigger-bit and --trigger-polarity read the trigger channel" in err


def test_a_24_bit_bdf_is_stored_code_for_code(session, store, tmp_path):
    # One 5 mV artefact: a per-trial 16-bit range would have a 0.15 µV step; the BDF's is 1/32 µV.
    path = tmp_path / "artefact.bdf"
    write_saga_file(session, path, bowden_bit=None, artefact_uv=5000.0)
    result = import_emg(store, path, ImportOptions(trigger_channel=TRIGGER, channel_map=SAGA_CHANNELS))
    assert result.trials == (1, 2, 3)
    codes = {label: s.digital for s in edfio.read_bdf(path).signals if (label := s.label) in SAGA_CHANNELS}
    first = _first_samples(session, store)
    with StudyStore(store) as opened:
        rows = opened.read_sql(
            "SELECT trial_id, muscle, first_sample, gain, offset_v, data FROM emg_chunks ORDER BY 1, 2, 3"
        )
        for trial in session.trials:
            emg = opened.trial_emg(trial.trial_id)
            assert emg is not None
            for label, muscle in SAGA_CHANNELS.items():
                mine = rows[(rows.trial_id == trial.trial_id) & (rows.muscle == muscle)]
                stored = np.concatenate([emg_chunks.decode_columns(b)["codes"] for b in mine["data"]])
                assert stored.dtype == np.int32
                source = codes[label][first[trial.trial_id] : first[trial.trial_id] + stored.size]
                np.testing.assert_array_equal(stored, source)  # code for code
                gain = float(mine["gain"].iloc[0])
                assert gain == pytest.approx(2 * 262_144e-6 / (2**24 - 1), rel=1e-12)  # 1/32 µV
                volts = emg[muscle].to_numpy()
                assert np.unique(np.round(np.diff(np.sort(np.unique(volts))) / gain)).min() == 1.0
    trial_1 = session.trials[0]
    assert len(np.unique(codes["UNI1"][first[1] : first[1] + len(trial_1.samples)])) > 1738


def test_a_codec_fault_while_replacing_emg_loses_nothing(session, store, tmp_path, monkeypatch, capsys):
    old = tmp_path / "old.edf"
    write_saga_file(session, old, bowden_bit=None)
    args = ["--trigger-channel", TRIGGER, *MAP]
    assert main(["emg", "import", str(store), str(old), *args]) == 0
    with StudyStore(store) as opened:
        before = opened.read_sql("SELECT * FROM emg_chunks ORDER BY trial_id, muscle, first_sample")
        events_before = opened.read_sql("SELECT * FROM events WHERE kind = 'emg_import' ORDER BY trial_id")
    new = tmp_path / "new.bdf"
    write_saga_file(session, new, bowden_bit=None, artefact_uv=100.0)
    real = emg_chunks.encode_columns

    def faulty(columns, **kwargs):  # a codec that drops the last sample of every block
        return real({name: values[:-1] for name, values in columns.items()}, **kwargs)

    monkeypatch.setattr(emg_chunks, "encode_columns", faulty)
    code = main(["emg", "import", str(store), str(new), *args, "--replace"])
    err = capsys.readouterr().err.strip()
    assert code == 1 and "\n" not in err
    assert err.startswith("bowden: error: new.bdf, trial 1: EMG of 'anterior_deltoid' from sample 0")
    assert "nothing written, the stored EMG kept" in err
    with StudyStore(store) as opened:
        after = opened.read_sql("SELECT * FROM emg_chunks ORDER BY trial_id, muscle, first_sample")
        events_after = opened.read_sql("SELECT * FROM events WHERE kind = 'emg_import' ORDER BY trial_id")
        assert opened.trial_emg(1) is not None
    assert after.equals(before) and events_after.equals(events_before)
    monkeypatch.setattr(emg_chunks, "encode_columns", real)
    assert main(["emg", "import", str(store), str(new), *args, "--replace"]) == 0
