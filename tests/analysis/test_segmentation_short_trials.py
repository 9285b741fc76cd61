"""Empty, too-short and broken traces give a RecordingError that says why, never a numpy error."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from bowden.analysis import SegmentationParameters, segment_repetitions
from bowden.analysis.segmentation import MIN_CYCLE_SAMPLES, find_cycles
from bowden.contracts import TRIAL_COLUMNS, TRIAL_ELEVATION, TRIAL_REFERENCE_ELEVATION, TRIAL_TIME
from bowden.errors import RecordingError


@pytest.mark.parametrize(("size", "message"), [
    (0, "the trial has no samples"),
    (1, "only 1 sample:"),
    (2, "only 2 samples"),
    (3, "only 3 samples"),
])
def test_too_short_traces_are_named(size: int, message: str) -> None:
    time = np.arange(size) / 500.0
    elevation = np.linspace(0.35, 1.75, size)
    with pytest.raises(RecordingError, match=message) as caught:
        find_cycles(time, elevation)
    assert f"at least {MIN_CYCLE_SAMPLES}" in str(caught.value)


def test_four_samples_are_enough_for_one_cycle() -> None:
    # low, high, low, still low: the shortest trace that holds a whole cycle.
    cycles = find_cycles([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 0.0, 0.0])
    assert [(c.start_s, c.turn_s, c.end_s) for c in cycles] == [(0.0, 1.0, 2.0)]


def test_a_non_finite_elevation_names_its_row() -> None:
    elevation = np.array([0.0, 1.0, math.nan, 0.0])
    with pytest.raises(RecordingError, match="not finite at row 2"):
        find_cycles(np.arange(4.0), elevation)


def test_time_and_elevation_of_different_length_are_refused() -> None:
    with pytest.raises(RecordingError, match="time has 4 samples but elevation has 3"):
        find_cycles(np.arange(4.0), np.zeros(3))


def test_an_empty_stored_trial_fails_with_a_recording_error() -> None:
    # What the store hands back for a trial that stopped before its first control cycle.
    empty = pd.DataFrame({name: pd.Series(dtype=np.float64) for name in TRIAL_COLUMNS})
    for source in ("auto", "reference"):
        with pytest.raises(RecordingError, match="no samples"):
            segment_repetitions(empty, SegmentationParameters(source=source))  # type: ignore[arg-type]
    assert {TRIAL_TIME, TRIAL_REFERENCE_ELEVATION, TRIAL_ELEVATION} <= set(empty.columns)
