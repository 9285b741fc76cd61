"""``bowden export --bids``: the official validator passes it, and what it holds reads back as stored."""

from __future__ import annotations

import gzip
import json
import shutil
from pathlib import Path

import edfio
import numpy as np
import pandas as pd
import pytest
from tests.study.reduced_study import SETTINGS

from bowden import __version__
from bowden.analysis.emg.read import decode_source
from bowden.cli import main
from bowden.contracts import TRIAL_COLUMNS, TRIAL_ELEVATION, TRIAL_TIME
from bowden.store.study_store import StudyStore

from .conftest import Validate


@pytest.fixture(scope="module")
def exported(small_study: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("bids") / "dataset"
    assert main(["export", "--bids", str(out), str(small_study), "--power-line-hz", "50"]) == 0
    return out


def _emg_file(bids: Path, trial_id: int) -> Path:
    (path,) = bids.glob(f"sub-*/emg/*_run-{trial_id}_emg.edf")
    return path


def test_the_official_validator_finds_no_error(exported: Path, bids_errors: Validate) -> None:
    assert bids_errors(exported) == []


def test_the_validator_catches_a_broken_export(exported: Path, bids_errors: Validate, tmp_path: Path) -> None:
    # The check itself can fail: a placement scheme outside the spec's levels is an error.
    broken = tmp_path / "broken"
    shutil.copytree(exported, broken)
    channels = next(broken.glob("sub-*/emg/*_channels.tsv"))
    channels.write_text(channels.read_text().replace("\tother\t", "\tSENIAM\t"))
    assert {issue["code"] for issue in bids_errors(broken)} == {"TSV_VALUE_INCORRECT_TYPE"}


def test_the_emg_codes_and_volts_read_back_as_stored(small_study: Path, exported: Path) -> None:
    with StudyStore(small_study / "study.db") as store:
        for trial_id in store.trials_with_emg()[:3]:
            stored, volts = store.trial_emg_codes(trial_id), store.trial_emg(trial_id)
            assert volts is not None
            path = _emg_file(exported, trial_id)
            edf = edfio.read_edf(path)
            channels = pd.read_csv(path.with_name(path.name.replace("_emg.edf", "_channels.tsv")), sep="\t",
                                   dtype={"gain_v": str, "offset_v": str})
            assert list(channels["muscle"]) == list(stored)
            for signal, row in zip(edf.signals, channels.itertuples(), strict=True):
                assert signal.label == row.name
                codes = signal.digital
                np.testing.assert_array_equal(codes, stored[row.muscle].codes)  # bit for bit
                exact = decode_source(codes, float(row.gain_v), float(row.offset_v))
                np.testing.assert_array_equal(exact, volts[row.muscle].to_numpy())
                # The header's 8-character range alone: within half a step of the store's volts (so
                # rounding gives the codes back), 0.23 steps at worst measured.
                step = stored[row.muscle].gain_v
                physical = signal.data * {"uV": 1e-6, "mV": 1e-3, "V": 1.0}[signal.physical_dimension]
                assert np.max(np.abs(physical - volts[row.muscle].to_numpy())) < 0.5 * step
                assert signal.sampling_frequency == 2000.0


def test_mne_bids_reads_the_emg(small_study: Path, exported: Path) -> None:
    from mne_bids import BIDSPath, read_raw_bids

    with StudyStore(small_study / "study.db") as store:
        trial_id = store.trials_with_emg()[1]
        volts = store.trial_emg(trial_id)
        participant = store.trial_table().set_index("id").loc[trial_id, "participant"]
    assert volts is not None
    path = BIDSPath(root=exported, subject=participant, task="armelevation", run=trial_id, datatype="emg",
                    suffix="emg", extension=".edf")
    raw = read_raw_bids(path, verbose="ERROR")
    emg_file = Path(str(path.fpath))
    channels = pd.read_csv(emg_file.with_name(emg_file.name.replace("_emg.edf", "_channels.tsv")), sep="\t")
    muscles = dict(zip(channels["name"], channels["muscle"], strict=True))
    assert set(raw.get_channel_types()) == {"emg"}
    assert raw.info["sfreq"] == 2000.0 and raw.info["line_freq"] == 50
    data = raw.get_data()
    for index, name in enumerate(raw.ch_names):
        expected = volts[muscles[name]].to_numpy()
        assert data[index].shape == expected.shape
        assert np.max(np.abs(data[index] - expected)) < 1e-5 * np.max(np.abs(expected))


def test_the_loop_signals_and_the_elevation_read_back_as_stored(small_study: Path, exported: Path) -> None:
    with StudyStore(small_study / "study.db") as store:
        for trial_id in store.trials_with_samples()[:3]:
            samples = store.trial_samples(trial_id)
            (physio,) = exported.glob(f"sub-*/beh/*_run-{trial_id}_recording-loop_physio.tsv.gz")
            sidecar = json.loads(physio.with_name(physio.name.replace(".tsv.gz", ".json")).read_text())
            assert sidecar["Columns"] == list(TRIAL_COLUMNS)
            model = sidecar["CompensationModel"]
            assert model["document"]["format"] == "bowden.compensation_model"  # the study's model.json
            assert model["model_coefficients"] == store.trial_metadata(trial_id)["model_coefficients"]
            with gzip.open(physio, "rt") as text:
                back = _exact(pd.read_csv(text, sep="\t", header=None, names=sidecar["Columns"], dtype=str))
            for column in TRIAL_COLUMNS:
                np.testing.assert_array_equal(back[column].to_numpy(), samples[column].to_numpy())
            (motion,) = exported.glob(f"sub-*/motion/*_run-{trial_id}_motion.tsv")
            back = _exact(pd.read_csv(motion, sep="\t", header=None, dtype=str))
            np.testing.assert_array_equal(back[0].to_numpy(), samples[TRIAL_TIME].to_numpy())
            np.testing.assert_array_equal(back[1].to_numpy(), samples[TRIAL_ELEVATION].to_numpy())


def _exact(text: pd.DataFrame) -> pd.DataFrame:
    """Numbers parsed by Python's float (exact round trip of repr); n/a is NaN."""
    return text.apply(lambda column: np.array([np.nan if v == "n/a" else float(v) for v in column]))


def test_events_participants_questionnaires_and_description(small_study: Path, exported: Path) -> None:
    with StudyStore(small_study / "study.db") as store:
        trials = store.trial_table()
        answers = store.questionnaires()
        registry = store.participants()
    first = trials.iloc[0]
    events = pd.read_csv(next(exported.glob(f"sub-*/emg/*_run-{first['id']}_events.tsv")), sep="\t")
    trial_row = events[events["trial_type"] == "trial"].iloc[0]
    assert (trial_row["condition"], trial_row["speed"]) == (first["condition"], first["speed"])
    repetitions = list(range(1, SETTINGS.repetitions + 1))
    assert list(events.loc[events["trial_type"] == "repetition", "repetition"]) == repetitions
    assert events.loc[events["trial_type"] == "stop", "stop_reason"].item() == first["stop_reason"]

    participants = pd.read_csv(exported / "participants.tsv", sep="\t")
    assert list(participants["bowden_id"]) == list(registry["id"])
    np.testing.assert_array_equal(participants["height"], registry["height_m"])

    rpe = pd.read_csv(exported / "phenotype" / "borg_rpe.tsv", sep="\t").set_index("participant_id")
    stored = answers[answers["questionnaire"] == "borg_rpe"]
    for row in stored.itertuples():
        assert rpe.loc[f"sub-{row.participant}", f"{row.item}_{row.condition}"] == row.score

    description = json.loads((exported / "dataset_description.json").read_text())
    assert description["BIDSVersion"] == "1.11.0"
    assert description["GeneratedBy"][0] == {**description["GeneratedBy"][0], "Name": "bowden",
                                             "Version": __version__}


def test_export_refuses_a_directory_of_other_files_and_a_bad_flag(
    small_study: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    assert main(["export", "--bids", str(other), str(small_study)]) != 0
    assert "--bids" in capsys.readouterr().err
    assert (other / "notes.txt").read_text() == "mine" and len(list(other.iterdir())) == 1
    assert main(["export", "--bids", str(tmp_path / "new"), str(small_study), "--power-line-hz", "0"]) != 0
    err = capsys.readouterr().err
    assert "--power-line-hz" in err and "Traceback" not in err
