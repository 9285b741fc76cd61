"""Matching trigger pulses to trials and the clock fit (bowden.analysis.emg.sync)."""

from __future__ import annotations

import numpy as np
import pytest

from bowden.analysis.emg.sync import clock_fit, match_pulses
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


def _command_edges(latency_s: np.ndarray, span_s: float = 1185.0) -> tuple[np.ndarray, np.ndarray]:
    """Three trials' edges on a recording without drift, as a command trigger stores them.

    Each edge's send took ``latency_s`` (the issue measured 22–51 ms); the line changed near the end
    of it (a program's start-up comes first), while the store keeps the middle: the stored host time
    is 0.4 × latency early. The first command is the slowest (a cold start).
    """
    zeros = np.array([0.0, 0.5, 1.0]) * span_s
    true = np.column_stack([zeros + 0.0123, zeros + 60.0]).ravel()
    recording = true - 4.2  # the amplifier started 4.2 s before: offset only, no drift
    stored = true - 0.4 * latency_s
    return recording, stored


def test_command_latency_is_not_reported_as_drift():
    latency = np.repeat([0.051, 0.036, 0.022], 2)
    recording, stored = _command_edges(latency)
    fit = clock_fit(recording, stored, uncertainty_s=latency)
    assert not fit.drift_resolved and fit.slope == 1.0 and fit.drift_ppm == 0.0
    assert fit.drift_bound_ppm > 10.0
    # The offset is off by the latency's mean bias only (the edges' own uncertainty).
    assert abs(fit.offset_s - 4.2) < 0.5 * latency.max()
    assert "drift not resolved by the edges" in fit.describe() and "command trigger" in fit.describe()
    # Without the stored uncertainties the same edges fit a spurious drift.
    assert abs(clock_fit(recording, stored).drift_ppm) > 5.0


def test_a_real_drift_is_resolved_through_command_latency_and_gpio_edges_outweigh_it():
    latency = np.repeat([0.051, 0.036, 0.022], 2)
    recording, stored = _command_edges(latency)
    recording = recording * (1.0 + 80e-6)  # the amplifier's clock runs 80 ppm fast
    fit = clock_fit(recording, stored, uncertainty_s=latency)
    assert fit.drift_resolved and abs(fit.drift_ppm - 80.0) < fit.drift_bound_ppm
    # Two GPIO edges (microseconds) among command edges: they set the line.
    precise = latency.copy()
    precise[[0, 5]] = 2e-6
    stored_precise = stored.copy()
    stored_precise[[0, 5]] = recording[[0, 5]] / (1.0 + 80e-6) + 4.2
    fit = clock_fit(recording, stored_precise, uncertainty_s=precise)
    assert abs(fit.drift_ppm - 80.0) < 1.0


def test_a_residual_may_exceed_the_budget_by_half_its_edge_send_time_only():
    recording = np.array([0.0, 10.0, 20.0, 30.0])
    stored = recording + 5.0
    stored[2] += 0.008  # 8 ms off
    with pytest.raises(SyncError, match=r"beyond [0-9.]+ ms \(--max-residual-ms plus half"):
        clock_fit(recording, stored, uncertainty_s=[0.0, 0.0, 0.004, 0.0])
    fit = clock_fit(recording, stored, uncertainty_s=[0.03, 0.03, 0.03, 0.03])
    assert fit.n_events == 4
