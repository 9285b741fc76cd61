"""Preprocessing: zero-phase low-pass per segment, acceleration, steady-state selection, direction split."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from bowden.contracts import (
    BENCH_ELEVATION,
    BENCH_MOTOR_TORQUE,
    BENCH_MOTOR_VELOCITY,
    BENCH_TENSION,
    BENCH_TIME,
    BENCH_TRIAL,
)
from bowden.errors import ParameterError, RecordingError
from bowden.identify.preprocess import PreprocessSettings, bench_filter, bench_preprocess, bench_select
from bowden.identify.recording import bench_recording_from_frame


def frame_from(
    time_s: np.ndarray,
    *,
    torque: np.ndarray | float = 1.0,
    velocity: np.ndarray | float = 1.0,
    tension: np.ndarray | float = 20.0,
    elevation: np.ndarray | float = 1.0,
    trial: np.ndarray | None = None,
) -> pd.DataFrame:
    n = time_s.size
    frame = pd.DataFrame(
        {
            BENCH_TIME: time_s,
            BENCH_MOTOR_TORQUE: np.broadcast_to(torque, n),
            BENCH_MOTOR_VELOCITY: np.broadcast_to(velocity, n),
            BENCH_TENSION: np.broadcast_to(tension, n),
            BENCH_ELEVATION: np.broadcast_to(elevation, n),
        }
    )
    if trial is not None:
        frame[BENCH_TRIAL] = trial
    return frame


def test_zero_phase_butterworth_gain_matches_the_squared_magnitude() -> None:
    # filtfilt applies |H|² of a 3rd-order Butterworth: 1/(1 + (f/fc)^6) -> 1/2 at fc, ~1 at 1 Hz,
    # 1/(1 + 4^6) at 20 Hz, and no phase shift (the peak stays where it was).
    rate = 1000.0
    t = np.arange(0.0, 20.0, 1.0 / rate)
    for frequency, expected in ((1.0, 1.0 / (1.0 + 0.2**6)), (5.0, 0.5), (20.0, 1.0 / (1.0 + 4.0**6))):
        signal = 10.0 * np.sin(2.0 * np.pi * frequency * t)
        recording = bench_recording_from_frame(frame_from(t, tension=20.0 + signal))
        filtered = bench_filter(recording).tension_n - 20.0
        middle = slice(5000, 15000)  # away from the segment edges
        gain = np.sqrt(2.0 * np.mean(filtered[middle] ** 2)) / 10.0
        assert gain == pytest.approx(expected, rel=2e-3, abs=1e-5)
        if frequency < 10.0:
            lag = np.argmax(np.correlate(filtered[middle], signal[middle], "full")) - (10000 - 1)
            assert lag == 0


def test_filter_never_crosses_a_gap_or_a_trial() -> None:
    # Two plateaus of torque: 1 Nm then 3 Nm. Filtered across the jump they would ring and blend;
    # filtered per segment each plateau stays exactly constant up to its edge.
    rate = 200.0
    t = np.arange(0, 400) / rate
    torque = np.where(np.arange(400) < 200, 1.0, 3.0)
    with_gap = t.copy()
    with_gap[200:] += 1.0  # a one-second hole in the recording
    trial = np.where(np.arange(400) < 200, 1, 2)
    restarted = np.concatenate([t[:200], t[:200]])
    for frame in (frame_from(with_gap, torque=torque), frame_from(restarted, torque=torque, trial=trial)):
        filtered = bench_filter(bench_recording_from_frame(frame))
        assert filtered.n_segments == 2
        np.testing.assert_array_equal(filtered.segment, np.repeat([0, 1], 200))
        np.testing.assert_allclose(filtered.motor_torque_nm, torque, rtol=0.0, atol=1e-12)
    # The control case: without the gap the jump is smeared over its neighbours.
    smeared = bench_filter(bench_recording_from_frame(frame_from(t, torque=torque))).motor_torque_nm
    assert abs(smeared[199] - 1.0) > 0.1 and abs(smeared[200] - 3.0) > 0.1


def test_short_segments_are_left_out_and_counted() -> None:
    t = np.concatenate([np.arange(100) / 100.0, 5.0 + np.arange(10) / 100.0])
    filtered = bench_filter(bench_recording_from_frame(frame_from(t)))
    assert filtered.n_segments == 1
    assert filtered.n_unfiltered == 10
    assert np.all(np.isnan(filtered.motor_torque_nm[100:]))
    assert np.all(filtered.segment[100:] == -1)


def test_acceleration_is_the_derivative_of_the_filtered_velocity() -> None:
    # A slow velocity ramp (0.2 rad/s²) passes the 5 Hz filter unchanged, so its derivative is exact
    # away from the segment edges (the filter's start-up transient fades within a second).
    t = np.arange(0, 2000) / 500.0
    filtered = bench_filter(bench_recording_from_frame(frame_from(t, velocity=0.5 + 0.2 * t)))
    np.testing.assert_allclose(filtered.motor_acceleration_rad_s2[500:-500], 0.2, rtol=1e-4)
    np.testing.assert_allclose(
        filtered.motor_acceleration_rad_s2, np.gradient(filtered.motor_velocity_rad_s, t), rtol=1e-12
    )


def test_each_selection_criterion_with_hand_built_samples() -> None:
    # Constant signals filter to themselves, so every sample's fate follows from its raw values.
    n = 100
    t = np.arange(7 * n) / 100.0
    deg = math.radians
    velocity = np.repeat([0.5, -0.5, deg(10.0), 0.5, 0.5, 0.5, 0.5], n)
    elevation = np.repeat([deg(45), deg(45), deg(45), deg(15), deg(95), deg(45), deg(45)], n)
    torque = np.repeat([1.0, 1.0, 1.0, 1.0, 1.0, -0.1, 1.0], n)
    trial = np.repeat(np.arange(7), n)
    frame = frame_from(t, torque=torque, velocity=velocity, elevation=elevation, trial=trial)
    frame[BENCH_TIME] = np.tile(np.arange(n) / 100.0, 7)
    selection = bench_preprocess(bench_recording_from_frame(frame))
    block = trial
    assert np.all(selection.raising[block == 0]) and not np.any(selection.lowering[block == 0])
    assert np.all(selection.lowering[block == 1]) and not np.any(selection.raising[block == 1])
    assert not np.any(selection.selected[block == 2]) and not np.any(selection.criteria["speed"][block == 2])
    assert not np.any(selection.criteria["elevation"][(block == 3) | (block == 4)])
    assert not np.any(selection.criteria["torque"][block == 5])
    assert np.all(selection.selected[block == 6])
    assert selection.count("raising") == 2 * n and selection.count("lowering") == n
    # Acceleration: a ramp of 0.5 rad/s² (> 15 °/s² = 0.262) fails, 0.2 rad/s² passes.
    ramp_t = np.arange(1000) / 200.0
    for slope, passes in ((0.5, False), (0.2, True)):
        ramp = frame_from(ramp_t, velocity=1.0 + slope * ramp_t)
        accepted = bench_preprocess(bench_recording_from_frame(ramp)).criteria["acceleration"]
        assert bool(np.all(accepted[100:-100])) is passes


def test_thresholds_are_configurable() -> None:
    t = np.arange(300) / 100.0
    frame = frame_from(t, velocity=math.radians(10.0), elevation=math.radians(95.0))
    recording = bench_recording_from_frame(frame)
    assert bench_preprocess(recording).count("raising") == 0
    relaxed = PreprocessSettings(min_speed_rad_s=math.radians(5.0), max_elevation_rad=math.radians(100.0))
    assert bench_preprocess(recording, relaxed).count("raising") == 300
    filtered = bench_filter(recording, relaxed)
    assert bench_select(filtered, relaxed).count("raising") == 300


def test_rejection_report_counts_each_criterion() -> None:
    t = np.arange(300) / 100.0
    frame = frame_from(t, velocity=-1.0, elevation=math.radians(100.0))
    report = bench_preprocess(bench_recording_from_frame(frame)).rejection_report("lowering")
    assert report.startswith("of 300 samples moving lowering, 0 fail |spool speed| > 15 °/s")
    assert "300 fail 20° < elevation < 90°" in report


def test_sampling_too_slow_for_the_cutoff_names_the_row() -> None:
    t = np.arange(100) / 8.0  # 8 Hz: a 5 Hz cutoff is above Nyquist
    from bowden.identify.recording import RecordingLimits

    recording = bench_recording_from_frame(frame_from(t), limits=RecordingLimits(min_sampling_rate_hz=1.0))
    with pytest.raises(RecordingError, match=r"row 1 of <table> is sampled at 8 Hz, too slow"):
        bench_filter(recording)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("cutoff_hz", 0.0),
        ("filter_order", 2.5),
        ("filter_order", 0),
        ("min_speed_rad_s", -1.0),
        ("max_abs_acceleration_rad_s2", float("nan")),
        ("min_elevation_rad", 2.0),
        ("gap_factor", 1.0),
        ("min_torque_nm", float("inf")),
    ],
)
def test_settings_are_validated(field: str, value: float) -> None:
    with pytest.raises(ParameterError, match=field):
        PreprocessSettings(**{field: value})  # type: ignore[arg-type]
