"""A straight multi-lane road along +x as a `SemanticMap` test double, with intersection zones.

Lane i's centreline is y = i·width (lane 0 rightmost, lanes to the left at larger y). A pose more than
width/2 + margin from the queried (or nearest) lane, or a non-finite pose, raises OffMapError.
"""

from __future__ import annotations

import numpy as np

from tracks.map_api import LaneCoord, OffMapError
from tracks.pose import Pose


class FakeStraightMap:
    def __init__(
        self,
        lanes: int = 2,
        width: float = 3.5,
        margin: float = 1.0,
        intersections: tuple[tuple[float, float], ...] = (),
    ) -> None:
        self.lanes = lanes
        self.width = width
        self.margin = margin
        self.intersections = intersections

    def project(self, pose: Pose, lane: int | None = None) -> LaneCoord:
        if not pose.is_finite():
            raise OffMapError(f"pose {pose} is not finite")
        i = min(max(round(pose.y / self.width), 0), self.lanes - 1) if lane is None else lane
        offset = pose.y - i * self.width
        if abs(offset) > self.width / 2 + self.margin:
            raise OffMapError(f"pose {pose} is {offset:.2f} m from lane {i}")
        return LaneCoord(i, pose.x, offset)

    def lane_dev(self, pose: Pose, lane: int | None = None) -> float:
        return self.project(pose, lane).l

    def lane_width(self, pose: Pose, lane: int | None = None) -> float:
        self.project(pose, lane)
        return self.width

    def lane_point(self, pose: Pose, lane: int | None = None) -> tuple[np.ndarray, float]:
        c = self.project(pose, lane)
        return np.array([c.s, c.lane * self.width]), 0.0

    def lane_curvature(self, pose: Pose, lane: int | None = None) -> float:
        self.project(pose, lane)
        return 0.0

    def is_intersection(self, pose: Pose) -> bool:
        self.project(pose)
        return any(lo <= pose.x <= hi for lo, hi in self.intersections)
