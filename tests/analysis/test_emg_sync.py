"""Matching trigger pulses to trials and the clock fit (bowden.analysis.emg.sync)."""

from __future__ import annotations

import numpy as np
import pytest

from bowden.analysis.emg.sync import match_pulses
from bowden.errors import SyncError


def test_pulses_near_every_trial_but_off_one_line_name_the_trial_not_an_index_error():
    # Both pulses fall within the matching window of trials 4 and 5, but trial 4's end edge is
    # 10 ms off: no line through the four edges stays within 2 × 2 ms (the reproduction).
    with pytest.raises(SyncError) as raised:
        match_pulses([[0, 10], [25, 35]], [[0, 10.01], [25, 35]], [4, 5])
    message = str(raised.value)
    assert "\n" not in message
    assert "trial 4's end edge" in message and "--max-residual-ms" in message
    assert "trial 5's" not in message


def test_the_edge_off_the_line_is_found_among_many():
    trials = np.array([[10.0 * k, 10.0 * k + 5.0] for k in range(6)])
    pulses = trials - 3.0
    pulses[3, 0] += 0.008  # trial 13's start edge 8 ms late in the recording
    with pytest.raises(SyncError, match=r"trial 13's start edge -[67]\.\d ms off the line"):
        match_pulses(pulses, trials, [10, 11, 12, 13, 14, 15])
