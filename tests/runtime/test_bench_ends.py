"""The bench's learned stopping points: moved along the range by the cuff's geometry, carried over a
restart by anchoring on a pose both runs learned, and the excursion a fast stroke is expected to
carry the arm past its rest (issue 26, item 3)."""

from __future__ import annotations

import json
import math

import pytest

from bowden.errors import RecordingError
from bowden.model.geometry import CuffGeometry
from bowden.runtime.bench_ends import LearnedEnds

GEOMETRY = CuffGeometry()  # a = 0.12 m, b = 0.18 m, ψ = 160°
RADIUS_M = 0.035
LOW, HIGH = math.radians(20.0), math.radians(110.0)


def cable_m(elevation_deg: float) -> float:
    """The straight cable between exit and anchor, by the law of cosines (hand-derived)."""
    alpha = math.radians(160.0 - elevation_deg)
    return math.sqrt(0.12**2 + 0.18**2 - 2 * 0.12 * 0.18 * math.cos(alpha))


def test_a_point_is_moved_along_the_range_by_the_cable_it_shortens():
    ends = LearnedEnds(GEOMETRY, RADIUS_M)
    ends.learn((HIGH, 1.0, 1.0), math.radians(108.0), 4.0)
    expected = 4.0 + (cable_m(108.0) - cable_m(110.0)) / RADIUS_M
    assert ends.stop((HIGH, 1.0, 1.0)) == pytest.approx(expected, rel=1e-12)
    assert expected > 4.0  # further up: more cable reeled in
    assert ends.stop((HIGH, 1.0, -1.0)) is None and ends.stop((HIGH, 2.0, 1.0)) is None


def test_a_resumed_run_anchors_the_earlier_points_on_a_pose_both_learned():
    before = LearnedEnds(GEOMETRY, RADIUS_M)
    before.learn((HIGH, 1.0, 1.0), HIGH, 4.5)
    before.learn((LOW, 1.0, -1.0), LOW, 0.4)
    saved = json.loads(json.dumps(before.to_json()))  # through the journal
    after = LearnedEnds(GEOMETRY, RADIUS_M, saved)
    assert after.stop((LOW, 1.0, -1.0)) is None  # the spool's origin moved: unknown until anchored
    # The restarted bench rests at 109° arriving upwards, its spool 7 rad further on.
    spool_at_109 = 4.5 + (cable_m(110.0) - cable_m(109.0)) / RADIUS_M  # before: less cable reeled in
    after.learn((HIGH, 1.0, 1.0), math.radians(109.0), spool_at_109 + 7.0)
    assert after.stop((LOW, 1.0, -1.0)) == pytest.approx(7.4, rel=1e-12)
    assert after.stop((HIGH, 1.0, 1.0)) == pytest.approx(11.5, rel=1e-12)
    assert after.to_json()["points"] == [after.to_json()["points"][0]]  # one set: all anchored


def test_a_fast_stroke_aims_short_by_its_expected_excursion():
    ends = LearnedEnds(GEOMETRY, RADIUS_M)
    key = (HIGH, 0.5, 1.0)
    ends.learn(key, HIGH, 4.5)
    ends.note_excursion(key, 4.0, math.radians(4.0))
    # Not run at 5 rad/s yet: 4° × (5/4)² × 1.5 = 9.375°, allowed 5° past the end: aim 4.375° short.
    assert math.degrees(ends.expected_excursion(key, 5.0)) == pytest.approx(9.375)
    aimed = 4.5 - (cable_m(110.0 - 4.375) - cable_m(110.0)) / RADIUS_M  # less cable reeled in
    assert ends.stop(key, 5.0, allowed_rad=math.radians(5.0)) == pytest.approx(aimed, rel=1e-9)
    ends.note_excursion(key, 5.0, math.radians(8.0))
    assert math.degrees(ends.expected_excursion(key, 5.0)) == pytest.approx(9.6)  # seen, and a fifth
    assert math.degrees(ends.expected_excursion(key, 3.0)) == pytest.approx(8.0)  # a faster one's
    assert ends.stop(key, 1.0, allowed_rad=math.radians(10.0)) == pytest.approx(4.5)
    reloaded = LearnedEnds(GEOMETRY, RADIUS_M, json.loads(json.dumps(ends.to_json())))
    assert reloaded.expected_excursion(key, 5.0) == pytest.approx(ends.expected_excursion(key, 5.0))


def test_a_damaged_journal_entry_is_one_error():
    with pytest.raises(RecordingError, match="damaged"):
        LearnedEnds(GEOMETRY, RADIUS_M, {"points": [[[1.0, 2.0, "x"]]]})


def test_a_stroke_never_aims_further_short_than_it_is_allowed_to():
    # The CI failure: a −1 rad/s lowering's excursion of 2.5° (the IMU's noise on a busy host)
    # extrapolated to 4 rad/s is 2.5° × 16 × 1.5 = 60°, more than the 50° range: the stroke braked
    # where it started, learned nothing, and failed three times. Capped at 25° short, it travels.
    ends = LearnedEnds(GEOMETRY, RADIUS_M)
    low, key = math.radians(20.0), (math.radians(20.0), 1.0, -1.0)
    ends.learn(key, low, 0.4)
    ends.note_excursion(key, 1.0, math.radians(2.5))
    assert math.degrees(ends.expected_excursion(key, 4.0)) == pytest.approx(60.0)
    capped = ends.stop(key, 4.0, allowed_rad=math.radians(5.0), most_short_rad=math.radians(25.0))
    aimed = 0.4 - (cable_m(45.0) - cable_m(20.0)) / RADIUS_M  # the spool's stop with the arm at 45°
    assert capped == pytest.approx(aimed, rel=1e-9)
    uncapped = ends.stop(key, 4.0, allowed_rad=math.radians(5.0))
    assert uncapped == pytest.approx(0.4 - (cable_m(75.0) - cable_m(20.0)) / RADIUS_M, rel=1e-9)
