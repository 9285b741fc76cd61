"""A reduced study end to end: bench → identification → cohort → trials → analysis → stats → report.

The issue's size: 2 participants, 1 repetition per trial (which the analysis then keeps: the paper's
dropped first repetition is the only one). The study and its ``bowden analyze --export`` are made once
per process and shared with other files (tests/study/reduced_study.py).
"""

import hashlib
import json
import re
import shutil

import numpy as np
import pytest
from tests.study.reduced_study import SETTINGS

from bowden.cli import main
from bowden.errors import ParameterError
from bowden.store.ownership import FILES_MANIFEST, files_not_written_by_study
from bowden.store.study_store import StudyStore
from bowden.study.pipeline import StudySettings, run_study
from bowden.study.report import html as report_html


@pytest.fixture(scope="module")
def study(shared_study):
    return shared_study


def test_every_stage_ran_and_the_report_is_labelled_simulated(study):
    assert study.trials_simulated == 2 * 4 * 3 and study.trials_skipped == 0
    text = study.report.read_text(encoding="utf-8")
    assert "SIMULATED" in text and "not human data" in text
    for caption in (
        "Tension tracking RMSE (N), simulated vs the paper",
        "Shoulder torque tracking RMSE (Nm), simulated vs the paper",
        "RMSE of the percent error (%), simulated vs the paper",
        "Elevation RMSE and SPARC, mean (SD) and GLMM p-values, simulated",
        "iEMG while raising: mean (SD) and GLMM p-values, simulated",
        "Friedman tests across conditions (simulated)",
    ):
        assert caption in text
    assert text.count("data:image/png;base64,") >= 5
    assert "nan" not in re.sub(r"<[^>]+>", " ", text).lower().split()
    assert "<script" not in text and "http://" not in text and "https://" not in text


def test_every_caption_of_a_simulated_report_says_simulated(study):
    text = study.report.read_text(encoding="utf-8")
    captions = re.findall(r"<caption>(.*?)</caption>", text, re.S)
    captions += re.findall(r"<figcaption>(.*?)</figcaption>", text, re.S)
    assert len(captions) >= 15
    unlabelled = [c for c in captions if "simulated" not in c.lower()]
    assert not unlabelled, unlabelled


def test_the_report_has_the_papers_questionnaire_figures_and_whole_cycle_iemg(study):
    text = study.report.read_text(encoding="utf-8")
    assert "Median discomfort per body site and condition, seen from behind" in text  # the Nordic map
    assert "Borg RPE (6–20) per condition" in text and "perceived fatigue (1–7) per condition" in text
    assert "iEMG over the entire cycle: mean (SD) and GLMM p-values, simulated" in text
    # Wide tables scroll in their own box; no table shows a bare 0, 1, 2… index column.
    assert text.count('<div class="table-scroll">') >= text.count("<table")
    assert not re.search(r"<tbody>\s*<tr>\s*<th>0</th>", text)
    assert "<td>None</td>" not in text  # unknown values read as missing


def test_outcomes_are_finite_and_stored(study):
    with StudyStore(study.store) as store:
        outcomes = store.outcomes()
        assert len(store.completed_trials()) == 24
        assert set(store.questionnaires()["participant"]) == {"P01", "P02"}
    values = outcomes[outcomes["measure"].isin(["tension_rmse_n", "elevation_rmse_rad", "sparc"])]["value"]
    assert len(values) > 0 and np.isfinite(values).all()
    # Tension errors exist only where a suit was worn.
    tension = outcomes[outcomes["measure"] == "tension_rmse_n"]
    assert set(tension["condition"]) == {"pretension", "support_25", "support_50"}
    # One repetition per trial, kept (there is no second to fall back on), in each phase.
    assert set(tension["repetition"]) == {1}
    assert len(tension) == 2 * 3 * 3 * 3  # participants × suit conditions × speeds × phases


def test_each_trial_records_the_models_hash_and_the_study_lists_its_files(study):
    """Issue 27: a trial is traceable to its model.json; the directory says which files are the study's."""
    model_sha256 = hashlib.sha256(study.model.read_bytes()).hexdigest()
    with StudyStore(study.store) as store:
        trials = store.read_sql("SELECT condition, metadata FROM trials")
    metadata = [json.loads(text) for text in trials["metadata"]]
    assert {m["model_sha256"] for m in metadata} == {model_sha256}
    assert all(m["model_coefficients"]["raising"]["slope_m"] > 0 for m in metadata)
    compensation = {c: m["compensation"] for c, m in zip(trials["condition"], metadata, strict=True)}
    suit = {"pretension": "paper", "support_25": "paper", "support_50": "paper"}
    assert compensation == {"no_suit": None, **suit}
    assert files_not_written_by_study(study.directory, ["bench.parquet", "model.json", "report.html"]) == []
    listed = json.loads((study.directory / FILES_MANIFEST).read_text())["files"]
    assert set(listed) == {"bench.parquet", "model.json", "report.html"}
    text = study.report.read_text(encoding="utf-8")
    trials = text[text.index('<h2 id="trials">'):text.index('<h2 id="methods">')]
    assert f"{model_sha256[:12]} (model.json)" in trials and "#1–#24" not in trials  # no-suit trials apart


def test_a_second_run_resumes_without_simulating_again(study, tmp_path, monkeypatch):
    # The resumed run analyses the store and writes the report again. Its figures, 10 s of its 16 s of
    # CPU, would be drawn from the same store by the code that drew the first run's (which the tests
    # above read), so they are left blank here; in a copy, so that the shared report keeps its own.
    directory = shutil.copytree(study.directory, tmp_path / "study")
    monkeypatch.setattr(report_html, "figure_png", lambda job: b"")
    again = run_study(SETTINGS, directory, workers=1)
    assert again.trials_simulated == 0 and again.trials_skipped == 24


def test_other_settings_in_the_same_directory_are_refused(study):
    with pytest.raises(ParameterError, match="--force"):
        run_study(StudySettings(participants=4, repetitions=2, quick_bench=True), study.directory)


def test_analyze_command_on_the_store(shared_export):
    # bowden analyze STUDY --export DIR --format csv --report FILE --quiet (tests/study/reduced_study.py)
    assert shared_export.code == 0
    assert shared_export.report.exists() and (shared_export.tables / "outcomes.csv").exists()
    assert "analysed 24 trials" in shared_export.stdout


def test_analyze_command_on_a_missing_store(tmp_path, capsys):
    assert main(["analyze", str(tmp_path / "nothing")]) == 1
    assert "no study store" in capsys.readouterr().err


@pytest.mark.parametrize(("field", "value"), [("repetitions", 0), ("repetitions", 51), ("participants", 1)])
def test_settings_out_of_range_are_refused_by_name(field, value):
    with pytest.raises(ParameterError, match=f"{field} must be between"):
        StudySettings(**{field: value})


def test_no_table_of_the_report_is_wider_than_its_box(study, tmp_path):
    """Every table fits the page or scrolls in its own box (a table once made the page 1442 px wide)."""
    sync_api = pytest.importorskip("playwright.sync_api")
    from .report_layout import CHROMIUM, overflowing_tables

    if not CHROMIUM.exists():
        pytest.skip("Debian's chromium is not installed")
    text = study.report.read_text(encoding="utf-8")
    wide = "<table><caption>unboxed</caption><tr>" + "<td>wide cell 12345</td>" * 80 + "</tr></table>"
    broken = tmp_path / "broken.html"
    broken.write_text(text.replace("</body>", wide + "</body>"), encoding="utf-8")
    ours, (bad, overflow) = overflowing_tables([study.report, broken], sync_api)
    assert ours == ([], 0.0)
    assert bad == ["unboxed"] and overflow > 0  # the check sees a table that does not scroll


def test_each_iemg_colour_table_has_the_papers_beside_it(study):
    text = study.report.read_text(encoding="utf-8")
    for label in ("tab:iEMG_deltas_visual", "Table 2", "Table 3"):
        caption = f"The same in the paper ({label}), beside the simulated table above"
        assert caption in text
        ours = text.rindex("iEMG change between conditions", 0, text.index(caption))
        assert text.index(caption) - ours < 20_000  # right after the study's own table
