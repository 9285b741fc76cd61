import math

import numpy as np
import pandas as pd
import pytest

from bowden.analysis import SegmentationParameters, resample_repetition, segment_repetitions
from bowden.analysis.segmentation import Repetition, find_cycles
from bowden.contracts import TRIAL_ELEVATION, TRIAL_REFERENCE_ELEVATION, TRIAL_TIME
from bowden.errors import ParameterError, RecordingError
from bowden.protocol import MinimumJerkCycle

RATE = 200.0


def _trial(cycle: MinimumJerkCycle, reps: int = 10, lead_s: float = 1.0, tail_s: float = 1.0) -> pd.DataFrame:
    time = np.arange(0.0, lead_s + reps * cycle.period_s + tail_s, 1.0 / RATE)
    moving = (time >= lead_s) & (time <= lead_s + reps * cycle.period_s)
    reference = np.where(moving, cycle.elevation_rad(time - lead_s), cycle.low_rad)
    return pd.DataFrame({TRIAL_TIME: time, TRIAL_REFERENCE_ELEVATION: reference, TRIAL_ELEVATION: reference})


@pytest.mark.parametrize("peak_deg_s", [60.0, 120.0, 180.0])
def test_reference_cycles_start_turn_and_end_where_the_protocol_says(peak_deg_s):
    cycle = MinimumJerkCycle(peak_speed_rad_s=math.radians(peak_deg_s))
    seg = segment_repetitions(_trial(cycle))
    assert seg.source == "reference"
    assert seg.n_found == 10
    assert [r.number for r in seg.repetitions] == list(range(2, 11))
    for rep in seg.repetitions:
        k = rep.number - 1
        # Low plateaus: the repetition starts at the last low sample and ends at the first one.
        assert rep.start_s == pytest.approx(1.0 + k * cycle.period_s, abs=1.0 / RATE)
        assert rep.turn_s == pytest.approx(1.0 + (k + 0.5) * cycle.period_s, abs=1.0 / RATE)
        assert rep.end_s == pytest.approx(1.0 + (k + 1) * cycle.period_s, abs=1.0 / RATE)
        assert rep.turn_fraction == pytest.approx(0.5, abs=2.0 / (RATE * cycle.period_s))


def test_pauses_between_repetitions_are_not_part_of_them():
    cycle = MinimumJerkCycle(peak_speed_rad_s=math.radians(120.0))
    pieces = []
    for _ in range(10):
        t = np.arange(0.0, cycle.period_s + 0.5, 1.0 / RATE)
        pieces.append(
            np.where(
                t <= cycle.period_s, cycle.elevation_rad(np.minimum(t, cycle.period_s - 1e-9)), cycle.low_rad
            )
        )
    x = np.concatenate([np.full(100, cycle.low_rad), *pieces])
    t = np.arange(x.size) / RATE
    cycles = find_cycles(t, x)
    assert len(cycles) == 10
    assert [c.duration_s for c in cycles] == pytest.approx([cycle.period_s] * 10, abs=2.0 / RATE)


def test_fallback_to_measured_elevation_with_noise_and_lag():
    cycle = MinimumJerkCycle(peak_speed_rad_s=math.radians(120.0))
    trial = _trial(cycle)
    rng = np.random.default_rng(2)
    measured = np.interp(trial[TRIAL_TIME] - 0.08, trial[TRIAL_TIME], trial[TRIAL_REFERENCE_ELEVATION])
    trial[TRIAL_ELEVATION] = measured + math.radians(1.0) * rng.standard_normal(len(trial))
    trial[TRIAL_REFERENCE_ELEVATION] = np.nan
    seg = segment_repetitions(trial)
    assert seg.source == "elevation"
    assert len(seg.repetitions) == 9
    for rep in seg.repetitions:
        assert rep.turn_s == pytest.approx(1.0 + (rep.number - 0.5) * cycle.period_s + 0.08, abs=0.05)
    with pytest.raises(RecordingError, match="use source='elevation'"):
        segment_repetitions(trial, SegmentationParameters(source="reference"))


def test_wrong_repetition_count_is_a_clear_error():
    cycle = MinimumJerkCycle(peak_speed_rad_s=math.radians(180.0))
    trial = _trial(cycle, reps=7)
    with pytest.raises(RecordingError, match=r"found 7 complete repetitions.*expected 10"):
        segment_repetitions(trial)
    seg = segment_repetitions(trial, SegmentationParameters(expected_repetitions=None, drop_first=2))
    assert [r.number for r in seg.repetitions] == [3, 4, 5, 6, 7]
    with pytest.raises(RecordingError, match="does not move"):
        find_cycles(np.arange(10.0), np.zeros(10))
    with pytest.raises(ParameterError, match="drop_first"):
        SegmentationParameters(expected_repetitions=3, drop_first=3)


def test_a_cycle_cut_by_the_end_of_the_record_is_not_counted():
    cycle = MinimumJerkCycle(peak_speed_rad_s=math.radians(180.0))
    trial = _trial(cycle, reps=10, tail_s=0.0).iloc[:-30]  # stop during the last descent
    assert len(find_cycles(trial[TRIAL_TIME], trial[TRIAL_REFERENCE_ELEVATION])) == 9


def test_resampling_onto_normalised_time_is_exact_for_linear_signals():
    t = np.arange(0.0, 10.0, 0.01)
    rep = Repetition(number=1, start_s=2.005, turn_s=3.0, end_s=4.5)
    out = resample_repetition(t, np.column_stack([3.0 * t + 1.0, -t]), rep, 11)
    grid = 2.005 + np.linspace(0.0, 1.0, 11) * 2.495
    assert out[:, 0] == pytest.approx(3.0 * grid + 1.0, rel=1e-12)
    assert out[:, 1] == pytest.approx(-grid, rel=1e-12)
    with pytest.raises(RecordingError, match="outside the signal"):
        resample_repetition(t, t, Repetition(number=1, start_s=9.0, turn_s=9.5, end_s=11.0), 5)
