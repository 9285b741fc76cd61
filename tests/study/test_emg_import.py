"""`bowden emg import`: a session's amplifier recording (EDF, XDF and CSV) into the store.

The truth is known: every amplifier sample's host time (tests/study/emg_session.py). The import
sees only the files and the store's sync events, and must find the trials, fit the +80 ppm drift and
the offset, and store each trial's samples at their true loop times. The 20-minute session is read
where the span is what is checked: the alignment at both of its ends, and a drift that command
edges' latency must not fake. Every other check reads the same three trials 40 and 45 s apart (a
2-minute recording, a tenth of the data to write and read): a refused or partial import, whose
messages do not depend on the session's length; a repeated import; the outcomes of an imported EDF;
and an XDF's markers, where +80 ppm left unfitted would still move a trial by several times the
millisecond checked (between the first and the last edge, 92 s: 7 ms).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bowden.analysis import AnalysisParameters, SegmentationParameters, TrialMetadata, analyse_study
from bowden.analysis.emg.channels import SAGA_CHANNELS
from bowden.cli import main
from bowden.contracts import MUSCLES, TRIAL_TIME
from bowden.store.study_store import StudyStore
from bowden.study.emg.importer import ImportOptions, import_emg
from bowden.study.emg.stored import emg_imports

from .emg_session import (
    TRIGGER,
    Session,
    direct_store,
    simulate_session,
    write_csv,
    write_edf,
    write_xdf,
)

MAP = ["--channels", "saga"]
SHORT_ZEROS_S = (10_000.0, 10_040.0, 10_085.0)  # gaps unequal, as the long session's: a part matches one run


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Session:
    return simulate_session(tmp_path_factory.mktemp("session"))


def _store_copy(session: Session, tmp_path: Path) -> Path:
    """A fresh copy of the session's store (trials and sync events, no EMG)."""
    copy = tmp_path / "study.db"
    shutil.copyfile(session.store, copy)
    return copy


@pytest.fixture
def store(session: Session, tmp_path: Path) -> Path:
    return _store_copy(session, tmp_path)


@pytest.fixture(scope="module")
def short(tmp_path_factory: pytest.TempPathFactory) -> Session:
    """The same three trials 40 and 45 s apart: a 2-minute recording."""
    return simulate_session(tmp_path_factory.mktemp("short"), zeros_s=SHORT_ZEROS_S)


@pytest.fixture(scope="module")
def short_edf(short: Session, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("short_edf") / "P01_session.edf"
    write_edf(short, path)
    return path


@pytest.fixture
def short_store(short: Session, tmp_path: Path) -> Path:
    return _store_copy(short, tmp_path)


def _alignment_errors(session: Session, store: Path) -> dict[int, float]:
    """Per trial, the largest |stored loop time - true loop time| of its samples, s.

    Which amplifier sample a stored row is comes from its value (the store keeps the samples), so
    a boundary sample taken or left by a slightly different fit does not count as misalignment.
    """
    recording_v = 1e-6 * session.emg_uv()[:, 0]
    errors = {}
    with StudyStore(store) as opened:
        for trial in session.trials:
            emg = opened.trial_emg(trial.trial_id)
            assert emg is not None and list(emg.columns) == [TRIAL_TIME, *MUSCLES]
            guess = int(session.trial_span(trial)[0])
            candidates = np.arange(guess - 2, guess + 3)
            first = int(candidates[np.argmin(np.abs(recording_v[candidates] - emg[MUSCLES[0]].iloc[0]))])
            n = first + np.arange(len(emg))
            np.testing.assert_allclose(
                emg[MUSCLES[0]], recording_v[n], rtol=0, atol=1e-3 * np.max(np.abs(recording_v[n]))
            )
            truth = session.host_time(n) - trial.zero_host_s
            errors[trial.trial_id] = float(np.max(np.abs(emg[TRIAL_TIME].to_numpy() - truth)))
    return errors


def _outcomes(store: Path) -> pd.DataFrame:
    with StudyStore(store) as opened:
        items = [
            (TrialMetadata(participant=t.participant, condition=t.condition, speed=t.speed), samples, emg)
            for t, samples, emg in opened.iter_trials()
        ]
    # As bowden analyze does: each trial's own repetition count, the first one dropped.
    segmentation = SegmentationParameters(expected_repetitions=None, drop_first=1)
    table = analyse_study(items, AnalysisParameters(segmentation=segmentation)).outcomes
    return table.set_index(
        ["participant", "condition", "speed", "repetition", "phase", "measure"]
    ).sort_index()


def _assert_same_outcomes(imported: Path, direct: Path) -> None:
    a, b = _outcomes(imported), _outcomes(direct)
    assert a.index.equals(b.index)
    emg_measures = a.index.get_level_values("measure").str.contains("emg|iemg", case=False)
    assert emg_measures.any()  # EMG outcomes are among those compared
    # The import keeps the file's own samples; the direct path stores float volts as 16-bit codes of
    # the trial's peak / 32767, whose rounding moves EMG outcomes by up to ~1e-5 of their value.
    np.testing.assert_allclose(a["value"].to_numpy(), b["value"].to_numpy(), rtol=5e-5, atol=0.0)


@pytest.mark.parametrize("ramp_samples", [2.0, 0.0], ids=["band-limited edges", "hard step edges"])
def test_edf_import_is_within_a_millisecond_at_both_ends_of_a_20_minute_session(
    session, store, tmp_path, ramp_samples, capsys
):
    path = tmp_path / "session.edf"
    write_edf(session, path, ramp_samples=ramp_samples)
    assert main(["emg", "import", str(store), str(path), "--trigger-channel", TRIGGER, *MAP]) == 0
    out = capsys.readouterr().out
    assert "imported EMG of trial(s) 1, 2, 3" in out and "drift +80.0 ppm" in out
    errors = _alignment_errors(session, store)
    span_s = session.trials[-1].zero_host_s - session.trials[0].zero_host_s
    assert span_s > 1150.0  # the first and last trial are ~20 minutes apart
    print(
        f"alignment error per trial ({ramp_samples=}): "
        + ", ".join(f"{e * 1e6:.3f} µs" for e in errors.values())
    )
    assert max(errors.values()) < 1e-3
    if ramp_samples:  # an edge the interpolation resolves: the fit is exact up to rounding
        assert max(errors.values()) < 1e-6


def test_outcomes_from_the_imported_edf_equal_those_of_the_same_emg_stored_directly(
    short, short_store, short_edf, tmp_path
):
    options = ImportOptions(trigger_channel=TRIGGER, channel_map=SAGA_CHANNELS)
    result = import_emg(short_store, short_edf, options)
    assert result.trials == (1, 2, 3) and abs(result.fit.drift_ppm - 80.0) < 0.01
    assert result.fit.max_residual_s < 1e-6
    from bowden.analysis.emg.read import read_emg_edf

    decoded = read_emg_edf(short_edf, channels=list(SAGA_CHANNELS)).values
    _assert_same_outcomes(short_store, direct_store(short, tmp_path / "direct.db", decoded))


def test_xdf_with_bowden_markers_is_imported_on_the_controller_clock(short, short_store, tmp_path):
    path = tmp_path / "session.xdf"
    write_xdf(short, path)
    result = import_emg(short_store, path, ImportOptions(channel_map=SAGA_CHANNELS))
    assert result.via == "markers" and result.trials == (1, 2, 3) and result.fit.n_events == 6
    errors = _alignment_errors(short, short_store)
    print("XDF alignment error per trial: " + ", ".join(f"{e * 1e6:.3f} µs" for e in errors.values()))
    assert max(errors.values()) < 1e-3
    decoded = 1e-6 * short.emg_uv()
    _assert_same_outcomes(short_store, direct_store(short, tmp_path / "direct.db", decoded))


def test_the_same_file_again_is_a_no_op_and_another_needs_replace(short_store, short_edf, tmp_path, capsys):
    store, edf = short_store, short_edf
    args = ["emg", "import", str(store), str(edf), "--trigger-channel", TRIGGER, *MAP]
    assert main(args) == 0
    with StudyStore(store) as opened:
        before = opened.read_sql(
            "SELECT trial_id, muscle, first_sample, start_time_s, data FROM emg_chunks ORDER BY 1, 2, 3"
        )
    assert main(args) == 0
    assert "nothing new to import; trial(s) 1, 2, 3 already from this file" in capsys.readouterr().out
    other = tmp_path / "other.edf"
    shutil.copyfile(edf, other)
    with other.open("r+b") as file:  # the same signals under another recording field: another file
        file.seek(88)
        file.write(b"Startdate 01-JAN-2026 X X X".ljust(80))
    assert main(["emg", "import", str(store), str(other), "--trigger-channel", TRIGGER, *MAP]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "EMG already stored for trial 1 from P01_session.edf" in err
    assert "--replace" in err
    with StudyStore(store) as opened:
        after = opened.read_sql(
            "SELECT trial_id, muscle, first_sample, start_time_s, data FROM emg_chunks ORDER BY 1, 2, 3"
        )
    pd.testing.assert_frame_equal(before, after)
    assert (
        main(["emg", "import", str(store), str(other), "--trigger-channel", TRIGGER, *MAP, "--replace"]) == 0
    )
    with StudyStore(store) as opened:
        assert {meta["file"] for meta in emg_imports(opened).values()} == {"other.edf"}
        assert len(opened.read_sql("SELECT DISTINCT trial_id, muscle FROM emg_chunks")) == 3 * len(MUSCLES)


def _refused(store: Path, path: Path, *extra: str, capsys: pytest.CaptureFixture[str]) -> str:
    code = main(["emg", "import", str(store), str(path), *extra])
    err = capsys.readouterr().err.strip()
    assert code == 1 and err.startswith("bowden: error: ") and "\n" not in err, err
    with StudyStore(store) as opened:  # nothing half-imported
        assert opened.trials_with_emg() == []
    return err


def _edf(session: Session, path: Path, **changes: object) -> Path:
    write_edf(session, path, **changes)  # type: ignore[arg-type]
    return path


def test_a_recording_of_part_of_the_session_is_imported_for_those_trials(short, short_store, tmp_path):
    path = _edf(short, tmp_path / "part.edf", pulses=[1, 2])
    result = import_emg(short_store, path, ImportOptions(trigger_channel=TRIGGER, channel_map=SAGA_CHANNELS))
    assert result.trials == (2, 3)


def test_a_missing_trigger_pulse_names_the_trials_that_matched(short, short_store, tmp_path, capsys):
    # The amplifier missed the second trial's pulse (the line was unplugged for it).
    path = _edf(short, tmp_path / "missed.edf", pulses=[0, 2])
    err = _refused(short_store, path, "--trigger-channel", TRIGGER, *MAP, capsys=capsys)
    assert "2 trigger pulses do not all match the store's trials: pulses 1–1 match trials 1, pulse 2" in err
    assert "matches no trial" in err


def test_more_pulses_than_trials_are_refused(short, short_store, short_edf, capsys):
    with StudyStore(short_store) as opened:
        opened._db.execute("DELETE FROM events WHERE trial_id = 3")
        opened._db.commit()
    err = _refused(short_store, short_edf, "--trigger-channel", TRIGGER, *MAP, capsys=capsys)
    assert "3 trigger pulses but the store has 2 trials with sync events (trials 1, 2)" in err


def test_drift_beyond_the_tolerance_is_refused(short, short_store, tmp_path, capsys):
    short.drift_ppm = 300.0
    try:
        path = _edf(short, tmp_path / "drift.edf")
    finally:
        short.drift_ppm = 80.0
    err = _refused(short_store, path, "--trigger-channel", TRIGGER, *MAP, capsys=capsys)
    assert "drift +300 ppm" in err and "beyond the 200 ppm tolerance" in err


def test_a_residual_beyond_2_ms_is_refused(short, short_store, tmp_path, capsys):
    # The second trial's end edge is 3 ms late in the recording: inside the matching window, off the fit.
    path = _edf(short, tmp_path / "late.edf", late_s=[0.0, 0.003])
    err = _refused(short_store, path, "--trigger-channel", TRIGGER, *MAP, capsys=capsys)
    assert "ms off the fit, beyond 2 ms" in err


def test_an_edge_off_the_line_of_all_others_names_the_file_and_the_trial(
    short, short_store, tmp_path, capsys
):
    # 6 ms late: inside the matching window, but no line through the edges fits within 2 × 2 ms.
    path = _edf(short, tmp_path / "late6.edf", late_s=[0.0, 0.006])
    err = _refused(short_store, path, "--trigger-channel", TRIGGER, *MAP, capsys=capsys)
    assert err.startswith("bowden: error: late6.edf: ") and "trial 2's end edge" in err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--trigger-channel", TRIGGER, *MAP, "--rate", "1000"], "trial 1: sampling rate is 2000.16 Hz"),
        (["--trigger-channel", TRIGGER], "unknown channel labels UNI1"),
        (["--trigger-channel", "TRIG", *MAP], "lacks channel(s) ['TRIG']"),
        ([*MAP], "give --trigger-channel NAME"),
    ],
)
def test_wrong_rate_labels_and_channels_are_refused(short_store, short_edf, args, message, capsys):
    assert message in _refused(short_store, short_edf, *args, capsys=capsys)


def test_a_map_naming_an_absent_label_and_a_flat_channel_are_refused(
    short, short_store, short_edf, tmp_path, capsys
):
    mapping = {**SAGA_CHANNELS}
    mapping["UNI42"] = mapping.pop("UNI8")
    (tmp_path / "map.json").write_text(json.dumps(mapping))
    err = _refused(
        short_store, short_edf, "--trigger-channel", TRIGGER, "--channels", str(tmp_path / "map.json"),
        capsys=capsys,
    )
    assert "lacks channel(s) ['UNI42']" in err
    # The pectoralis electrode was plugged into UNI9, which recorded nothing.
    mapping = {**SAGA_CHANNELS}
    mapping["UNI9"] = mapping.pop("UNI8")
    (tmp_path / "map.json").write_text(json.dumps(mapping))
    path = _edf(short, tmp_path / "flat.edf", flat="UNI9")
    err = _refused(
        short_store, path, "--trigger-channel", TRIGGER, "--channels", str(tmp_path / "map.json"),
        capsys=capsys,
    )
    assert "trial 1: channel 'pectoralis_major' is flat" in err


def test_a_recording_without_pulses_and_stores_without_trials_are_refused(
    short, short_store, short_edf, tmp_path, capsys
):
    path = _edf(short, tmp_path / "quiet.edf", pulses=[])
    err = _refused(short_store, path, "--trigger-channel", TRIGGER, *MAP, capsys=capsys)
    assert "holds no pulse: the recording covers no trial" in err
    empty = tmp_path / "empty.db"
    StudyStore(empty).close()
    assert "holds no completed trial" in _refused(
        empty, short_edf, "--trigger-channel", TRIGGER, *MAP, capsys=capsys
    )
    no_sync = tmp_path / "nosync.db"
    shutil.copyfile(short.store, no_sync)
    with StudyStore(no_sync) as opened:
        opened._db.execute("DELETE FROM events WHERE kind = 'sync'")
        opened._db.commit()
    refused = _refused(no_sync, short_edf, "--trigger-channel", TRIGGER, *MAP, capsys=capsys)
    assert "has sync events" in refused


def test_analyze_reports_which_trials_had_emg_and_from_which_file(short, short_store, tmp_path, capsys):
    path = _edf(short, tmp_path / "P01_part.edf", pulses=[0, 1])
    assert main(["emg", "import", str(short_store), str(path), "--trigger-channel", TRIGGER, *MAP]) == 0
    report = tmp_path / "report.html"
    assert main(["analyze", str(short_store), "--report", str(report), "--quiet"]) == 0
    assert "analysed 3 trials" in capsys.readouterr().out
    text = report.read_text()
    assert "EMG of trials #1–#2: imported from P01_part.edf (synchronised by trigger: drift +80.0 ppm" in text
    assert "EMG of trial 3: none" in text


def test_a_csv_export_is_imported_like_an_edf(tmp_path, capsys):
    # Trials of 6.5 s, 11 and 13 s apart: a 39 s export (writing it, every value formatted, is the cost).
    short = simulate_session(tmp_path, zeros_s=(100.0, 111.0, 124.0), offset_s=2.2)
    path = tmp_path / "export.csv"
    write_csv(short, path)
    args = ["emg", "import", str(short.store), str(path), "--trigger-channel", TRIGGER, *MAP]
    assert main([*args, "--csv-volts-per-unit", "1e-6"]) == 0
    assert "imported EMG of trial(s) 1, 2, 3 (by trigger: 6 sync events" in capsys.readouterr().out
    assert max(_alignment_errors(short, short.store).values()) < 1e-6


def _as_command_trigger(store: Path, latency_s: dict[int, float]) -> None:
    """Rewrite the store's sync events as a command trigger leaves them: each send took
    ``latency_s[trial]``, the line changed near its end, the event keeps the middle (0.4 × early)."""
    from bowden.runtime.sync_events import SYNC_KIND, SyncEvent

    with StudyStore(store) as opened:
        rows = opened.read_sql(
            "SELECT rowid, trial_id, time_s, message FROM events WHERE kind = ?", (SYNC_KIND,)
        )
        for rowid, trial, time_s, message in rows.itertuples(index=False):
            event = SyncEvent.from_event(time_s, message)
            early = 0.4 * latency_s[int(trial)]
            moved = SyncEvent(
                edge=event.edge,
                time_s=event.time_s - early,
                host_time_s=event.host_time_s - early,
                uncertainty_s=latency_s[int(trial)],
                trigger="command 'gpioset ...'",
            )
            opened._db.execute(
                "UPDATE events SET time_s = ?, message = ? WHERE rowid = ?",
                (moved.time_s, moved.message(), rowid),
            )
        opened._db.commit()


def test_command_trigger_latency_on_a_recording_without_drift_gives_no_drift(session, store, tmp_path):
    # The issue: 22–51 ms command edges made a recording with no drift import with +79 ppm.
    _as_command_trigger(store, {1: 0.051, 2: 0.036, 3: 0.022})
    session.drift_ppm = 0.0
    try:
        path = _edf(session, tmp_path / "no_drift.edf")
    finally:
        session.drift_ppm = 80.0
    result = import_emg(store, path, ImportOptions(trigger_channel=TRIGGER, channel_map=SAGA_CHANNELS))
    assert result.trials == (1, 2, 3)
    assert result.fit.drift_ppm == 0.0 and not result.fit.drift_resolved
    assert "drift not resolved by the edges" in result.describe()
    assert "aligned no better than that" in result.describe()
    with StudyStore(store) as opened:
        provenance = emg_imports(opened)[1]
    assert provenance["max_edge_uncertainty_s"] == 0.051 and provenance["drift_resolved"] is False
