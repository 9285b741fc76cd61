"""The study-like segment's mannequin moves with a wearer's motor noise (``MotorNoise``): an
Ornstein–Uhlenbeck torque of the protocol's size and correlation time, the same draws for both
compensations of a (support, speed) cell so that their strokes stay paired."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bowden.errors import ParameterError
from bowden.protocol.bench import MotorNoise, StudyBlock, StudyStrokes

PERIOD_S = 0.001


def _series(strokes: StudyStrokes, block: StudyBlock, feedforward_nm: float, n: int) -> np.ndarray:
    noise = MotorNoise(strokes, block, PERIOD_S)
    return np.array([noise.torque_nm(feedforward_nm) for _ in range(n)])


def test_the_noise_has_the_protocol_s_size_and_correlation_time():
    strokes = StudyStrokes()
    block = StudyBlock(index=0, support=0.5, speed="V2", compensation="paper")
    series = _series(strokes, block, feedforward_nm=0.0, n=400_000)  # 400 s: 1600 correlation times
    # A stationary unit OU process scaled by 0.5 Nm: SD 0.5; its autocorrelation at lag τ is 1/e.
    assert np.std(series) == pytest.approx(0.5, rel=0.06)
    lag = round(strokes.motor_noise_time_s / PERIOD_S)
    correlation = np.corrcoef(series[:-lag], series[lag:])[0, 1]
    assert correlation == pytest.approx(math.exp(-1.0), abs=0.05)
    # The signal-dependent part: 1 % of a 10 Nm feed-forward adds a fifth to the size, same draws.
    louder = _series(strokes, block, feedforward_nm=10.0, n=1000)
    assert np.allclose(louder, series[:1000] * (0.5 + 0.1) / 0.5)


def test_both_compensations_of_a_cell_meet_the_same_noise_and_other_cells_other_noise():
    strokes = StudyStrokes()
    def block(index: int, speed: str, compensation: str) -> StudyBlock:
        return StudyBlock(index=index, support=0.25, speed=speed, compensation=compensation)

    paper = _series(strokes, block(6, "V1", "paper"), 1.0, 500)
    dynamic = _series(strokes, block(7, "V1", "dynamic"), 1.0, 500)
    other = _series(strokes, block(8, "V2", "paper"), 1.0, 500)
    assert np.array_equal(paper, dynamic)
    assert not np.allclose(paper, other)
    # One support alone (bench validate --support 0.25) meets the noise of the whole protocol's 25 %.
    alone = _series(StudyStrokes(supports=(0.25,)), block(0, "V1", "paper"), 1.0, 500)
    assert np.array_equal(paper, alone)


def test_a_noise_out_of_range_is_refused():
    with pytest.raises(ParameterError, match="motor noise"):
        StudyStrokes(motor_noise_nm=-0.1)
    with pytest.raises(ParameterError, match="motor noise"):
        StudyStrokes(motor_noise_time_s=0.0)


def test_every_candidate_of_a_fit_meets_the_same_noise_and_the_validation_other_noise():
    from bowden.identify.study_fit import fit_grid
    from bowden.protocol.bench import StudyFit

    fit = StudyFit(grid=fit_grid(), speeds=("V1", "V2"))
    strokes = fit.strokes(StudyStrokes())
    blocks = fit.blocks()
    at_v1 = [block for block in blocks if block.speed == "V1"]
    assert [block.candidate for block in at_v1] == [-1, *range(12)]  # the paper's, then the grid's
    series = [_series(strokes, block, 1.0, 300) for block in at_v1]
    assert all(np.array_equal(series[0], other) for other in series[1:])
    v2 = next(block for block in blocks if block.speed == "V2")
    assert not np.allclose(series[0], _series(strokes, v2, 1.0, 300))
    # The validation's blocks at the fit's support and speed: held out, their own draws.
    validation = StudyBlock(index=0, support=0.5, speed="V1", compensation="dynamic")
    assert not np.allclose(series[0], _series(StudyStrokes(), validation, 1.0, 300))
