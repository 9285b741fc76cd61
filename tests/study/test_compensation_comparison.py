"""The dynamic compensation against the paper's on simulated suits, each identified on its own bench."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from bowden import contracts as c
from bowden.errors import ParameterError
from bowden.protocol.bench import BenchProtocol
from bowden.sim.plant_family import DEVELOPMENT_PLANT, named_plants, random_plants
from bowden.study.compensation.comparison import ComparisonSettings, compare_on_plant, summarise

QUICK = ComparisonSettings(
    participants=1,
    conditions=(c.CONDITION_PRETENSION, c.CONDITION_SUPPORT_50),
    speeds=("V1", "V3"),
    repetitions=3,
    bench=BenchProtocol(spool_speeds_rad_s=(1.0, 3.0, 6.0), loads_nm=(1.0, 3.0), repetitions=1),
)


_compared: dict[str, pd.DataFrame] = {}


def compared(name: str) -> pd.DataFrame:
    """``compare_on_plant`` of the named suit with :data:`QUICK`, once per process (the summary's test
    reads the same rows)."""
    if name not in _compared:
        _compared[name] = compare_on_plant(next(p for p in named_plants() if p.name == name), QUICK)
    return _compared[name]


@pytest.mark.parametrize("name", ["sticky", "imu-10ms"])
def test_dynamic_compensation_beats_the_paper_on_a_suit_it_was_not_developed_on(name: str) -> None:
    rows = compared(name)
    assert len(rows) == 2 * 2 * 2  # compensations × conditions × speeds
    assert np.isfinite(rows[["tension_rmse_n", "onset_peak_pct", "onset_dip_pct"]].to_numpy()).all()
    table = summarise(rows).iloc[0]
    assert table["rmse_ratio"] < 0.6
    assert table["peak_ratio"] < 0.6
    assert table["worse_conditions"] == 0


def test_the_family_differs_where_suits_differ_and_random_suits_are_reproducible() -> None:
    plants = named_plants()
    assert plants[0].name == DEVELOPMENT_PLANT
    assert len({p.name for p in plants}) == len(plants)
    assert len({repr(p.suit) for p in plants}) == len(plants)
    drawn = random_plants(3, 7)
    assert drawn == random_plants(3, 7) and drawn != random_plants(3, 8)
    assert all(0.01 <= p.suit.imu.latency_s <= 0.05 for p in drawn)
    with pytest.raises(ParameterError, match="count"):
        random_plants(0, 1)


def test_summary_counts_cells_where_the_dynamic_compensation_is_worse() -> None:
    rows = compared("sticky")  # 2 conditions x 2 speeds, the dynamic compensation better in each
    assert summarise(rows).iloc[0]["worse_conditions"] == 0
    dynamic = rows["compensation"] == "dynamic"
    one_cell = dynamic & (rows["condition"] == c.CONDITION_SUPPORT_50) & (rows["speed"] == "V3")
    worse = rows.copy()
    worse.loc[one_cell, "tension_rmse_n"] = 99.0
    assert summarise(worse).iloc[0]["worse_conditions"] == 1
    worse.loc[dynamic, "tension_rmse_n"] = 99.0
    assert summarise(worse).iloc[0]["worse_conditions"] == 4


def test_a_dynamic_study_reports_both_compensations_on_the_same_trials(tmp_path) -> None:
    from bowden.study.pipeline import StudySettings, run_study

    settings = StudySettings(
        participants=2, repetitions=2, quick_bench=True, store_emg=False, compensation="dynamic"
    )
    result = run_study(settings, tmp_path / "study", workers=1)  # the same results as on a pool
    report = result.report.read_text(encoding="utf-8")
    # The last occurrence: the table of contents names the section first.
    section = report[report.rindex("Beyond the paper: dynamic compensation") :]
    assert "Paper against dynamic compensation" in section and "(simulated)" in section
    assert section.count("<img") == 1
    for label in ("pre", "25%", "50%"):
        assert f">{label}<" in section
    # The musculoskeletal participants' posterior deltoid beside it (issue 30, item 5).
    assert "posterior deltoid lowering, musculoskeletal" in section
    assert "Musculoskeletal participants" in section or "not installed" in section
    # The study itself ran with the dynamic compensation, and says so in its settings.
    assert '"compensation": "dynamic"' in (tmp_path / "study" / "settings.json").read_text()
    with pytest.raises(ParameterError, match="other settings"):
        run_study(
            StudySettings(participants=2, repetitions=2, quick_bench=True, store_emg=False),
            tmp_path / "study",
            workers=1,
        )
