"""The paper's values: generated from its LaTeX and current, and a few numbers checked by hand."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

from bowden.errors import ParameterError
from bowden.study import paper_values as pv

ROOT = Path(__file__).resolve().parents[2]
PAPER = ROOT.parent / "shared" / "paper" / "sensorless-tension-control.tex"
if not PAPER.exists():
    PAPER = Path("/work/shared/paper/sensorless-tension-control.tex")


def _script() -> ModuleType:
    spec = importlib.util.spec_from_file_location(
        "extract_paper_values", ROOT / "scripts" / "extract_paper_values.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.mark.skipif(not PAPER.exists(), reason="the paper's LaTeX is not on this machine")
def test_the_generated_modules_are_current() -> None:
    script = _script()
    for name, text in script.render(PAPER.read_text(encoding="utf-8")).items():
        current = (ROOT / "src" / "bowden" / "study" / "paper_values" / name).read_text(encoding="utf-8")
        assert current == text, f"{name} is stale: run scripts/extract_paper_values.py {PAPER}"


def test_tracking_tables_hold_the_papers_numbers() -> None:
    assert pv.tension_rmse_n().loc["support_50", ("V3", "lowering")] == 9.07  # Table 1
    assert pv.torque_rmse_nm().loc["pretension", ("V1", "entire")] == 0.29  # Table 1
    assert pv.percent_error_rmse().loc["support_50", ("V3", "entire")] == 23.4  # S1
    raising = pv.peak_percent_error("raising")  # S2
    assert raising.loc["pretension", ("V3", "peak_error_pct")] == -3.2
    assert raising.loc["pretension", ("V3", "peak_error_sd")] == 112.0
    assert pv.peak_percent_error("lowering").loc["support_25", ("V2", "normalised_time_pct")] == 61.4  # S3
    with pytest.raises(ParameterError):
        pv.peak_percent_error("entire")


def test_kinematics_and_their_comparisons() -> None:
    table = pv.kinematics().set_index(["outcome", "speed", "condition"])
    assert table.loc[("elevation_rmse_deg", "V3", "support_50"), "mean"] == 13.888  # S4
    assert pv.kinematics_p("sparc")["condition"].value == 0.023
    speed_p = pv.kinematics_p("elevation_rmse_deg")["speed"]
    assert speed_p.upper_bound and speed_p.value == 0.001 and str(speed_p) == "< 0.001"
    conditions = pv.kinematic_pairs("condition").set_index(["outcome", "first", "second"])  # S5
    assert conditions.loc[("sparc", "support_50", "no_suit"), "change"] == 0.073
    assert str(conditions.loc[("sparc", "support_50", "no_suit"), "p"]) == "0.04"
    assert "elevation_rmse_deg" not in set(conditions.index.get_level_values("outcome"))  # N/A in S5
    speeds = pv.kinematic_pairs("speed").set_index(["outcome", "first", "second"])  # S6
    assert speeds.loc[("elevation_rmse_deg", "V1", "V3"), "change"] == -8.756


def test_iemg_tables() -> None:
    means = pv.iemg_means("entire").set_index(["muscle", "speed", "condition"])  # S7
    assert tuple(means.loc[("pectoralis_major", "V1", "no_suit")]) == (0.548, 0.075)
    assert pv.iemg_p("raising", "biceps")["condition"].value == 0.009  # S8
    pairs = pv.iemg_pairs("lowering").set_index(["muscle", "first", "second"])  # S12
    row = pairs.loc[("posterior_deltoid", "support_50", "no_suit")]
    assert (row["change"], row["percent"], row["p"].upper_bound) == (0.105, 31.7, True)
    whole = pv.iemg_pairs("entire").set_index(["muscle", "first", "second"])  # S10
    assert whole.loc[("medial_deltoid", "support_50", "pretension"), "percent"] == -16.3
    assert len(pv.iemg_pairs("raising")) == 48
    colours = {  # Table 2
        (row.muscle, row.first, row.second): (row.rgb, row.code)
        for row in pv.iemg_colours("raising").itertuples()
    }
    assert colours[("trapezius", "support_50", "no_suit")] == ((28, 255, 28), "**")
    assert colours[("posterior_deltoid", "pretension", "no_suit")][1] == ""


def test_questionnaire_results_of_the_text() -> None:
    assert str(pv.questionnaire_p("nordic", "lower_neck")) == "0.001"
    shoulder = pv.questionnaire_p("nordic", "right_shoulder")
    assert shoulder is not None and shoulder.upper_bound and shoulder.significant()
    rpe = pv.questionnaire_p("borg_rpe", "rpe")
    assert rpe is not None and rpe.value == 0.125 and not rpe.significant()
    assert pv.questionnaire_p("fatigue", "trapezius") == pv.P("0.397")
    assert pv.questionnaire_p("nordic", "hips") is None
    pairs = pv.nordic_pairs().set_index(["item", "from", "to"])
    assert str(pairs.loc[("right_shoulder", "pretension", "support_50"), "p"]) == "0.007"
    assert len(pairs) == 6 and set(pairs["direction"]) == {"increase"}


def test_a_p_value_is_checked() -> None:
    with pytest.raises(ParameterError):
        pv.P("n/a")
    with pytest.raises(ParameterError):
        pv.P("1.5")
    assert pv.P("< 0.05").significant() and not pv.P("0.05").significant()
