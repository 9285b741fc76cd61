"""Where the spool's target stands when the bench's arm rests at a range end: learned, kept, and carried over.

A stroke brakes so that the spool stops where it stood the last time the arm came to rest at that
end under the same load, arriving in the same direction (the sheath's friction and the cable's
stretch differ with both). These stopping points are learned as the run goes (after every stroke
and every positioning move that ends at rest near a range end) and are journalled with the
recording, so that a resumed run starts as informed as the run it continues.

Spool positions are the TDU's multi-turn encoder angle, whose origin and the cable's length on the
spool change whenever the bench restarts (the slack is taken up anew). So the points of an earlier
run are kept *unanchored* until the arm rests at a pose the earlier run also learned (same end, load
and direction of arrival): the difference of the two spool positions there is the shift of the
whole earlier set, which then joins the points of this run. A point is moved along the range by the
cuff's geometry: reeling in shortens the straight cable between the shoulder's exit and the arm's
anchor (:meth:`bowden.model.geometry.CuffGeometry.cable_length_m`), one spool radius per radian.

Where the arm rests is not where it turns: a fast stroke under a light load flings the arm past its
rest (raising, the cable goes slack as the spool brakes faster than the load can stop the arm;
lowering, the arm's momentum stretches the cable), by 10° at 5 rad/s and 0.5 Nm on the simulated
bench. So each stroke's *excursion* (how far past its rest it turned) is kept per end, load,
direction and speed, and a stroke aims its rest short of the end by what its excursion is expected
to carry it past half the range margin: the largest seen at its speed with a fifth more, or, at a
speed not run yet, the fastest slower one's scaled with the speed squared (the arm's kinetic
energy) and half again.
"""

from __future__ import annotations

import math
from typing import Any

from bowden.errors import RecordingError
from bowden.model.geometry import CuffGeometry

Key = tuple[float, float, float]  # (range end rad, load Nm, direction of arrival ±1)
Point = tuple[float, float]  # (elevation rad, spool rad) with the arm at rest
_SAME_SPEED_FACTOR = 1.2  # on the largest excursion seen at a stroke's own speed
_NEW_SPEED_FACTOR = 1.5  # on a slower speed's, scaled with the speed squared


class LearnedEnds:
    """The spool's stopping points of the bench's range ends.

    Parameters
    ----------
    geometry
        The cuff's geometry, to move a point along the range.
    spool_radius_m
        The TDU's pulley radius.
    earlier
        What earlier runs of the same recording learned (:meth:`to_json`'s output): their points
        unanchored, their excursions as they are.
    """

    def __init__(self, geometry: CuffGeometry, spool_radius_m: float, earlier: Any = None) -> None:
        self.geometry = geometry
        self.spool_radius_m = spool_radius_m
        self.points: dict[Key, Point] = {}
        earlier = earlier if isinstance(earlier, dict) else {}
        self.unanchored: list[dict[Key, Point]] = [
            group for group in map(_group_from_json, earlier.get("points", [])) if group]
        self.excursions: dict[Key, dict[float, float]] = {}
        for row in _group_rows(earlier.get("excursions", []), 5):
            self.note_excursion((row[0], row[1], row[2]), row[3], row[4])

    def spool_at(self, point: Point, elevation_rad: float) -> float:
        """The spool position that puts the arm at ``elevation_rad``, from a point of the same
        load and direction (the cable's stretch taken as equal)."""
        elevation, spool = point
        shortened_m = self.geometry.cable_length_m(elevation) - self.geometry.cable_length_m(elevation_rad)
        return spool + shortened_m / self.spool_radius_m

    def learn(self, key: Key, elevation_rad: float, spool_rad: float) -> None:
        """The arm rests at ``elevation_rad`` with the spool at ``spool_rad`` near ``key``'s end."""
        for group in list(self.unanchored):
            earlier = group.get(key)
            if earlier is None:
                continue
            shift = spool_rad - self.spool_at(earlier, elevation_rad)
            for other, (e, q) in group.items():
                self.points.setdefault(other, (e, q + shift))
            self.unanchored.remove(group)
        self.points[key] = (elevation_rad, spool_rad)

    def stop(self, key: Key, speed_rad_s: float = 0.0, allowed_rad: float = math.inf,
             unknown_rad: float = 0.0, most_short_rad: float = math.inf) -> float | None:
        """The spool position at which a stroke at ``speed_rad_s`` brings the arm to rest at ``key``'s
        end, or short of it by what its expected excursion (``unknown_rad`` before any stroke there
        was seen) carries it beyond ``allowed_rad`` past the end, by at most ``most_short_rad``; None
        before any rest there is known.

        The cap keeps a stroke moving: an excursion extrapolated from a slower speed grows with the
        speed squared, and the IMU's noise in a slow stroke's excursion (1–2° on a busy host) can make
        it span the whole range, so that the stroke would brake where it starts and learn nothing."""
        point = self.points.get(key)
        if point is None:
            return None
        end, _, direction = key
        expected = self.expected_excursion(key, speed_rad_s) if key in self.excursions else unknown_rad
        short_rad = min(max(expected - allowed_rad, 0.0), most_short_rad)
        return self.spool_at(point, end - direction * short_rad)

    def note_excursion(self, key: Key, speed_rad_s: float, excursion_rad: float) -> None:
        """A stroke at ``speed_rad_s`` to ``key``'s end turned ``excursion_rad`` past where it rested."""
        by_speed = self.excursions.setdefault(key, {})
        by_speed[speed_rad_s] = max(by_speed.get(speed_rad_s, 0.0), excursion_rad, 0.0)

    def expected_excursion(self, key: Key, speed_rad_s: float) -> float:
        """How far past its rest a stroke at ``speed_rad_s`` is expected to carry the arm (rad)."""
        by_speed = self.excursions.get(key, {})
        if speed_rad_s in by_speed:
            return _SAME_SPEED_FACTOR * by_speed[speed_rad_s]
        faster = [excursion for speed, excursion in by_speed.items() if speed > speed_rad_s]
        slower = [(speed, excursion) for speed, excursion in by_speed.items() if speed < speed_rad_s]
        expected = max(faster, default=0.0)
        if slower:
            speed, excursion = max(slower)
            expected = max(expected, _NEW_SPEED_FACTOR * excursion * (speed_rad_s / speed) ** 2)
        return expected

    def to_json(self) -> dict[str, Any]:
        """Every point set (this run's first) and every excursion, as JSON numbers."""
        return {"points": [_group_to_json(group) for group in (self.points, *self.unanchored) if group],
                "excursions": [[*key, speed, excursion] for key, by_speed in self.excursions.items()
                               for speed, excursion in by_speed.items()]}


def _group_to_json(group: dict[Key, Point]) -> list[list[float]]:
    return [[end, load, direction, elevation, spool] for (end, load, direction), (elevation, spool)
            in group.items()]


def _group_from_json(rows: Any) -> dict[Key, Point]:
    return {(r[0], r[1], r[2]): (r[3], r[4]) for r in _group_rows(rows, 5)}


def _group_rows(rows: Any, width: int) -> list[list[float]]:
    try:
        out = [[float(v) for v in row] for row in rows]
    except (TypeError, ValueError):
        raise RecordingError("what the bench journal learned about the bench is damaged") from None
    if not all(len(row) == width and all(math.isfinite(v) for v in row) for row in out):
        raise RecordingError("what the bench journal learned about the bench is damaged")
    return out
