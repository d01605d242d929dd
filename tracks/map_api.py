"""The semantic-map contract LD3 needs (paper Table 3), as a Protocol the defense types against.

Lateral deviation D is signed: + left of the lane centreline, - right (paper Appendix A).
Queries for a pose farther than a lane's half width plus a margin from every lane raise
`OffMapError`; callers on a vehicle (the defense) catch it and handle it as their algorithm says.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol

import numpy as np

from tracks.pose import Pose


class OffMapError(ValueError):
    """The queried pose is not on any lane of the map (or is not finite)."""


class LaneCoord(NamedTuple):
    """A pose projected onto a lane: lane index (0 = rightmost), arc length s, signed offset l (+ left)."""

    lane: int
    s: float
    l: float  # noqa: E741 - the lane-frame name of highway-env and the paper


class SemanticMap(Protocol):
    def project(self, pose: Pose, lane: int | None = None) -> LaneCoord:
        """Project onto the nearest lane (or onto `lane` when given)."""
        ...

    def lane_dev(self, pose: Pose, lane: int | None = None) -> float:
        """Signed lateral deviation D of the pose from the lane centreline (m, + left)."""
        ...

    def lane_width(self, pose: Pose, lane: int | None = None) -> float:
        """Width of the lane at the pose (m)."""
        ...

    def lane_point(self, pose: Pose, lane: int | None = None) -> tuple[np.ndarray, float]:
        """Closest centreline point (x, y) and the lane heading there (rad)."""
        ...

    def lane_curvature(self, pose: Pose, lane: int | None = None) -> float:
        """Signed centreline curvature at the projection (1/m, + turning left)."""
        ...

    def is_intersection(self, pose: Pose) -> bool:
        """True inside an intersection zone (no lane markings)."""
        ...
