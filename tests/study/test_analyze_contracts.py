"""``analyze_store`` reads each trial's metadata contract: its repetition count and its backend.

The stores are written through the study store's API with trials whose cycles are known exactly
(minimum-jerk references sampled at 100 Hz), so every count the analysis finds is hand-checkable.
An analysis writes its report with its figures, about 5 s of CPU even for a few trials, so the tests
that only read an analysed store share it (module fixtures).
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from bowden.cli import main
from bowden.contracts import BACKEND_CAN, BACKEND_SIM, TRIAL_COLUMNS
from bowden.errors import RecordingError, StoreError
from bowden.protocol import MinimumJerkCycle
from bowden.runtime.recorder import TrialInfo
from bowden.store.study_store import StudyStore
from bowden.study.analyze import AnalysisReport, analyze_store, data_kind, expected_repetitions

RATE_HZ = 100.0
CYCLE = MinimumJerkCycle(peak_speed_rad_s=math.radians(180.0))  # V3: one cycle in 5/3 s
LEAD_S = TAIL_S = 0.5


def trial_samples(cycles: int) -> pd.DataFrame:
    """``cycles`` V3 cycles after a rest, then a rest; the suit tracks the desired tension within 1 N."""
    time = np.arange(0.0, LEAD_S + cycles * CYCLE.period_s + TAIL_S, 1.0 / RATE_HZ)
    moving = (time >= LEAD_S) & (time <= LEAD_S + cycles * CYCLE.period_s)
    reference = np.where(moving, CYCLE.elevation_rad(np.clip(time - LEAD_S, 0.0, None)), CYCLE.low_rad)
    desired = 20.0 + 30.0 * np.sin(reference)
    return pd.DataFrame({
        "time_s": time,
        "reference_elevation_rad": reference,
        "elevation_rad": reference,
        "elevation_velocity_rad_s": np.gradient(reference, time),
        "desired_tension_n": desired,
        "moment_arm_m": np.full(time.size, 0.05),
        "commanded_torque_nm": 0.02 * desired,
        "motor_torque_nm": 0.02 * desired,
        "motor_velocity_rad_s": np.zeros(time.size),
        "tension_n": desired + np.sin(7.0 * time),
        "controller_state": np.ones(time.size, dtype=int),
        "fault_flags": np.zeros(time.size, dtype=int),
    }).loc[:, list(TRIAL_COLUMNS)]


def write_store(path: Path, trials: list[tuple[int, dict[str, Any]]]) -> Path:
    """A store of one participant's support_50/V3 trials: (cycles recorded, metadata) each."""
    with StudyStore(path) as store:
        for cycles, metadata in trials:
            info = TrialInfo(participant="P01", condition="support_50", speed="V3", support=0.5,
                             metadata=metadata)
            store.write_trial(info, trial_samples(cycles) if cycles else trial_samples(0).iloc[:0])
    return path


def kept_repetitions(store_path: Path) -> list[int]:
    with StudyStore(store_path) as store:
        outcomes = store.outcomes()
    return sorted(set(outcomes["repetition"]))


def title(report: Path) -> str:
    found = re.search(r"<h1>(.*?)</h1>", report.read_text(encoding="utf-8"))
    assert found is not None
    return found.group(1)


@dataclass(frozen=True)
class Analysed:
    """A store and what ``analyze_store`` made of it (the tests only read both)."""

    store: Path
    result: AnalysisReport


def analysed(directory: Path, trials: list[tuple[int, dict[str, Any]]]) -> Analysed:
    store = write_store(directory / "study.db", trials)
    return Analysed(store, analyze_store(store, directory / "report.html", workers=1))


@pytest.fixture(scope="module")
def own_counts_mixed(tmp_path_factory: pytest.TempPathFactory) -> Analysed:
    """A measured trial then two simulated ones, each with its own repetition count: 2, 3, and 4 in
    the old `bowden run` place (under "reference"). Read by the counts' test and the title's: a trial's
    backend labels the report, it does not enter the trial's analysis."""
    return analysed(tmp_path_factory.mktemp("own_counts_mixed"), [
        (2, {"backend": BACKEND_CAN, "repetitions": 2}),
        (3, {"backend": BACKEND_SIM, "repetitions": 3}),
        (4, {"backend": BACKEND_SIM, "reference": {"start_s": 0.5, "repetitions": 4}}),
    ])


@pytest.fixture(scope="module")
def one_repetition_simulated(tmp_path_factory: pytest.TempPathFactory) -> Analysed:
    """Two simulated trials of one repetition each (the one-repetition test and the title's read it)."""
    return analysed(tmp_path_factory.mktemp("one_repetition"),
                    [(1, {"backend": BACKEND_SIM, "repetitions": 1})] * 2)


def test_each_trial_is_checked_against_its_own_repetition_count(own_counts_mixed: Analysed) -> None:
    # The first trial's count (2) no longer stands for the others; the old `bowden run` place of
    # the count (under "reference") is still read.
    result = own_counts_mixed.result
    assert result.skipped == ()
    assert result.n_trials == 3
    # The first repetition of each trial is dropped: repetitions 2…4 remain.
    assert kept_repetitions(own_counts_mixed.store) == [2, 3, 4]
    assert result.outcomes.info.n_repetitions == 1 + 2 + 3


def test_unusable_trials_are_skipped_and_named(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    store = write_store(tmp_path / "study.db", [
        (2, {"backend": BACKEND_SIM, "repetitions": 2}),  # good
        (0, {"backend": BACKEND_SIM, "repetitions": 2}),  # stopped before its first cycle
        (2, {"backend": BACKEND_SIM, "repetitions": 3}),  # cut short
        (1, {"backend": BACKEND_SIM, "repetitions": 1}),  # nothing left once the first is dropped
        (2, {"backend": BACKEND_SIM, "repetitions": "two"}),
    ])
    with caplog.at_level(logging.WARNING, logger="bowden.study.analyze"):
        result = analyze_store(store, tmp_path / "report.html", workers=1)
    assert result.n_trials == 1
    reasons = dict(zip((2, 3, 4, 5), result.skipped, strict=True))
    assert reasons[2].startswith(
        "trial 2 (participant P01, support_50, V3) skipped: the trial has no samples"
    )
    assert "found 2 complete repetitions" in reasons[3] and "expected 3" in reasons[3]
    assert "holds 1 repetition" in reasons[4] and "dropped (adaptation)" in reasons[4]
    assert "'two' repetitions" in reasons[5]
    html = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert all(reason.split(":")[0] in html for reason in result.skipped)  # in the report's notes
    assert [r.getMessage() for r in caplog.records] == [f"bowden analyze: {r}" for r in result.skipped]


def test_bowden_analyze_analyses_the_good_trial_beside_an_empty_one(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, capsys: pytest.CaptureFixture[str]
) -> None:
    store = write_store(tmp_path / "study.db", [
        (2, {"backend": BACKEND_SIM, "repetitions": 2}),
        (0, {"backend": BACKEND_SIM, "repetitions": 1}),
    ])
    with caplog.at_level(logging.WARNING, logger="bowden.study.analyze"):
        code = main(["analyze", str(store), "--report", str(tmp_path / "r.html"), "--quiet"])
    assert code == 0, capsys.readouterr().err
    assert "analysed 1 trials, skipped 1 (see the report's notes)" in capsys.readouterr().out
    assert any("trial 2 (participant P01, support_50, V3) skipped: the trial has no samples" in r.getMessage()
               for r in caplog.records)


def test_a_store_with_no_usable_trial_says_which_and_why(tmp_path: Path) -> None:
    store = write_store(tmp_path / "study.db", [(0, {"backend": BACKEND_SIM, "repetitions": 2})])
    with pytest.raises(StoreError, match=r"no trial that can be analysed: trial 1 .* no samples"):
        analyze_store(store, tmp_path / "report.html", workers=1)


def test_one_repetition_trials_are_kept_when_no_trial_holds_more(one_repetition_simulated: Analysed) -> None:
    result = one_repetition_simulated.result
    assert result.skipped == () and result.outcomes.info.parameters.segmentation.drop_first == 0
    assert kept_repetitions(one_repetition_simulated.store) == [1]


def test_expected_repetitions_reads_the_agreed_key_then_the_old_place() -> None:
    assert expected_repetitions({"repetitions": 3, "reference": {"repetitions": 7}}) == 3
    assert expected_repetitions({"reference": {"repetitions": 7}}) == 7
    assert expected_repetitions({}) == 10  # the paper's count when nothing was recorded
    assert expected_repetitions({"repetitions": None, "reference": {"repetitions": 7}}) is None  # free run
    for bad in (0, -2, 2.5, True, "3"):
        with pytest.raises(RecordingError, match="not a positive whole number"):
            expected_repetitions({"repetitions": bad})


def test_a_free_run_keeps_the_cycles_it_holds(tmp_path: Path) -> None:
    # The real suit without a display: the wearer made 3 cycles and no count was set.
    store = write_store(tmp_path / "study.db", [(3, {"backend": BACKEND_CAN, "repetitions": None})])
    result = analyze_store(store, tmp_path / "report.html", workers=1)
    assert result.skipped == () and kept_repetitions(store) == [2, 3]


@pytest.mark.parametrize(("backends", "kind"), [
    ([BACKEND_SIM], "simulated"),
    (["simulation"], "simulated"),  # what `bowden study` wrote before the names were shared
    ([BACKEND_CAN], "measured"),
    ([None], "measured"),  # nothing recorded: never called simulated
    ([BACKEND_SIM, BACKEND_CAN], "mixed"),
    (["simulation", None], "mixed"),
])
def test_the_kind_of_data_follows_every_trials_backend(backends: list[str | None], kind: str) -> None:
    metadata = [{} if backend is None else {"backend": backend} for backend in backends]
    assert data_kind(metadata) == kind


def test_reports_say_simulated_measured_or_mixed_in_the_title(
    one_repetition_simulated: Analysed, own_counts_mixed: Analysed
) -> None:
    result = one_repetition_simulated.result
    assert result.data_kind == "simulated" and "SIMULATED" in title(result.report)

    result = own_counts_mixed.result  # trial 1 measured, trials 2 and 3 simulated
    assert result.data_kind == "mixed"
    assert title(result.report) == "bowden study report — MIXED: 1 measured and 2 simulated trials"
    html = result.report.read_text(encoding="utf-8")
    assert "measured trials (#1) and simulated trials (#2–#3)" in html  # runs, not a page of ids
    assert "Shoulder torque tracking RMSE (Nm), simulated vs the paper" in html  # never "measured"
    assert "measured vs the paper" not in html
