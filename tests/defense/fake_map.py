"""The straight multi-lane road test double: the defense benchmark's map, with a 1 m off-map margin."""

from __future__ import annotations

from testbed.defense.bench import StraightRoadMap


class FakeStraightMap(StraightRoadMap):
    def __init__(self, lanes: int = 2, width: float = 3.5, margin: float = 1.0,
                 intersections: tuple[tuple[float, float], ...] = ()) -> None:
        super().__init__(lanes, width, margin, intersections)
