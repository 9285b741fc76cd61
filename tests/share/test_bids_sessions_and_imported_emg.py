"""A lab store's shapes the simulated study lacks: several sessions per participant, EMG imported as
an amplifier's float32 counts at 2048 Hz for a prime number of samples, floats off any 24-bit step."""

from __future__ import annotations

import json
from pathlib import Path

import edfio
import numpy as np
import pandas as pd
import pytest

from bowden.analysis.emg.read import SourceChannel
from bowden.cli import main
from bowden.contracts import MUSCLES, TRIAL_COLUMNS, TRIAL_FAULT, TRIAL_STATE, TRIAL_TIME
from bowden.model.anthropometry import Subject
from bowden.protocol.session_plan import StudyProtocol
from bowden.share.emg_run import exact_values
from bowden.store.emg_chunks import encode_verified_emg
from bowden.store.sessions import SessionStore
from bowden.store.study_store import StudyStore
from bowden.store.trials import TrialInfo

from .conftest import validator_issues

PRIME_SAMPLES = 6151  # at 2048 Hz: no record of whole samples with an exact 8-character duration divides it
GAIN_UV = np.float32(0.01788139343)  # TMSi SAGA-like: 150 mV over 2^24 counts, float32 microvolts


def _samples(rows: int = 31) -> pd.DataFrame:
    time = np.arange(rows) / 100.0
    frame = pd.DataFrame({column: np.sin(time + i) for i, column in enumerate(TRIAL_COLUMNS)})
    frame[TRIAL_TIME] = time
    frame[TRIAL_STATE], frame[TRIAL_FAULT] = 1, 0
    return frame


def _import(store: StudyStore, trial_id: int, values: dict[str, np.ndarray], rate_hz: float) -> None:
    sources = {m: SourceChannel(codes=v, gain_v=1e-6) for m, v in values.items()}
    chunks = encode_verified_emg(sources, start_time_s=0.0, rate_hz=rate_hz)
    store.replace_emg({trial_id: chunks}, {trial_id: ("emg_import", json.dumps({"file": "x.xdf"}))})


@pytest.fixture(scope="module")
def lab_store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("lab") / "study.db"
    rng = np.random.default_rng(11)
    with StudyStore(path) as store:
        for participant in ("P01", "P02"):
            store.add_participant(participant, Subject(height_m=1.75, mass_kg=70.0, sex="female"))
        first, second, third = (
            store.write_trial(TrialInfo(participant=p, condition=c, speed="V2", support=s), _samples())
            for p, c, s in (("P01", "support_25", 0.25), ("P01", "support_50", 0.5),
                            ("P02", "support_25", 0.25))
        )
        counts = {m: np.rint(rng.normal(0, 3000, PRIME_SAMPLES)).astype(np.int64) for m in MUSCLES}
        # The host clock's measured rate of a 2048 Hz amplifier (the import's clock fit).
        _import(store, first, {m: (c * GAIN_UV).astype(np.float32) for m, c in counts.items()}, 2048.0011)
        codes16 = {m: rng.integers(-30000, 30000, 4096).astype(np.int16) for m in MUSCLES}
        _import(store, second, codes16, 2048.0)
        filtered = {m: rng.normal(0, 40.0, 3001).astype(np.float32) for m in MUSCLES}  # off any lattice
        _import(store, third, filtered, 1000.0)
    sessions = SessionStore(path)
    protocol = StudyProtocol(baseline=None, conditions=("support_25", "support_50"), speeds=("V2",))
    for trial_id in (first, second):  # one session per trial, the rest of each plan skipped
        session = sessions.create("P01", protocol, seed=1)
        sessions.trial_started(session.session_id, 1, trial_id)
        sessions.trial_ended(trial_id, completed=True, reason="completed")
        for step in session.steps[1:]:
            sessions.skip(session.session_id, step.step.position, "test")
    return path


@pytest.fixture(scope="module")
def exported(lab_store: Path) -> Path:
    out = lab_store.parent / "bids"
    assert main(["export", "--bids", str(out), str(lab_store), "--power-line-hz", "50",
                 "--authors", "A. Author", "--authors", "B. Author", "--license", "CC-BY-4.0",
                 "--manufacturer", "TMSi"]) == 0
    return out


def test_sessions_are_levels_and_the_validator_finds_no_error(exported: Path) -> None:
    issues = validator_issues(exported)
    assert [issue for issue in issues if issue["severity"] == "error"] == []
    names = sorted(p.relative_to(exported).as_posix() for p in exported.glob("sub-*/ses-*/emg/*_emg.?df"))
    assert [n.split("/")[1] for n in names] == ["ses-1", "ses-2", "ses-unplanned"]
    sessions = pd.read_csv(exported / "sub-P01" / "sub-P01_sessions.tsv", sep="\t")
    assert list(sessions["session_id"]) == ["ses-1", "ses-2"]
    assert list(sessions["bowden_session"]) == [1, 2]
    # The warnings that --authors, --license and --manufacturer answer are gone.
    warned = {(issue.get("subCode"), issue.get("location", "").split("/")[3]) for issue in issues
              if issue["severity"] == "warning" and issue.get("location", "").count("/") > 3}
    assert not {("Manufacturer", "emg")} & warned
    recommended = {issue.get("subCode") for issue in issues if issue["code"] == "JSON_KEY_RECOMMENDED"}
    assert not recommended & {"Authors", "License"}


def test_a_prime_length_float32_import_reads_back_exactly(lab_store: Path, exported: Path) -> None:
    from mne_bids import BIDSPath, read_raw_bids

    with StudyStore(lab_store) as store:
        stored = store.trial_emg_codes(1)
        volts = store.trial_emg(1)
    assert volts is not None
    path = BIDSPath(root=exported, subject="P01", session="1", task="armelevation", run=1, datatype="emg",
                    suffix="emg", extension=".bdf")
    raw = read_raw_bids(path, verbose="ERROR")
    assert raw.info["sfreq"] == 2048.0 and raw.n_times == 4 * 2048  # whole 1-s records, the last padded
    data = raw.get_data(reject_by_annotation="omit")  # the padding is marked BAD_ACQ_SKIP
    assert data.shape == (len(MUSCLES), PRIME_SAMPLES)
    sidecar = json.loads(Path(str(path.fpath)).with_suffix(".json").read_text())
    assert sidecar["RecordingDuration"] == PRIME_SAMPLES / 2048.0 and sidecar["Manufacturer"] == "TMSi"
    emg_file = Path(str(path.fpath))
    channels = pd.read_csv(emg_file.with_name(emg_file.name.replace("_emg.bdf", "_channels.tsv")), sep="\t",
                           dtype={"code_step": str})
    bdf = edfio.read_bdf(path.fpath)
    for index, row in enumerate(channels.itertuples()):
        values = stored[row.muscle].codes
        back = (bdf.signals[index].digital[:PRIME_SAMPLES] * float(row.code_step)).astype(np.float32)
        np.testing.assert_array_equal(back.view(np.uint32), values.view(np.uint32))  # bit for bit
        # The header's 8-character physical range alone: within one step of the file's 24-bit codes.
        step_v = float(row.code_step) * stored[row.muscle].gain_v
        assert np.max(np.abs(data[raw.ch_names.index(row.name)] - volts[row.muscle].to_numpy())) < step_v


def test_floats_off_any_step_keep_their_exact_values(lab_store: Path, exported: Path) -> None:
    with StudyStore(lab_store) as store:
        stored = store.trial_emg_codes(3)
    (channels_file,) = exported.glob("sub-P02/ses-unplanned/emg/*_channels.tsv")
    channels = pd.read_csv(channels_file, sep="\t")
    (exact_name,) = set(channels["exact_values"])
    exact = exact_values(exported / exact_name)
    for muscle, channel in stored.items():
        np.testing.assert_array_equal(exact[muscle].astype(np.float32).view(np.uint32),
                                      channel.codes.view(np.uint32))


def test_description_names_authors_and_licence(exported: Path, capsys: pytest.CaptureFixture[str],
                                               lab_store: Path) -> None:
    description = json.loads((exported / "dataset_description.json").read_text())
    assert description["Authors"] == ["A. Author", "B. Author"] and description["License"] == "CC-BY-4.0"
    assert main(["export", "--bids", str(lab_store.parent / "x"), str(lab_store), "--license", "CC BY"]) != 0
    err = capsys.readouterr().err
    assert "--license" in err and "Traceback" not in err
