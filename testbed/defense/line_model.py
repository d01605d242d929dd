"""Where a detection's lines are evidence of the car's offset: the map's curvature over the lines' near range.

A detector reports each line as a polynomial y(x) fitted to what it sees ahead (`LaneDetection`), and Alg. 3
reads its value at x = 0, an extrapolation back from the nearest ground in view (about 5 m ahead), where a
detector weighs its fit most. A lane that turns on a town corner's radius (10 m and less) within that near range is
no low-order y(x) there, and the value at x = 0 is metres off while the car is centred; a curve farther ahead or
of a wider radius leaves the near range to the line the car is on. `tight_turn` reads the map: the smallest
radius of the lane's centre from the station of a pose to `NEAR_RANGE` ahead, when under a bound. `followable`
withholds both lines there; it never changes a detection it keeps. The pose is the caller's to choose: LD3 passes
its dead-reckoned pose, one no MSF attacker moves.
"""

from __future__ import annotations

import dataclasses
import math

from testbed.lane_detection import LaneDetection
from tracks.map_api import OffMapError, SemanticMap
from tracks.pose import Pose

NEAR_RANGE = 12.0
"""m of lane ahead of the car's station whose curvature decides: the shipped detector's line errors rose past 0.1 m
from 10 m before Town02's corner of radius 6.2 m and jumped to metres 4 m before Town01's of 10.2 m."""
WALK_STEP = 1.0
"""Lane length between the curvature samples (m)."""


def tight_turn(smap: SemanticMap, pose: Pose, lane: int, radius: float) -> float | None:
    """The smallest radius (m) of `lane`'s centre from the station of `pose` to `NEAR_RANGE` ahead where it is under
    `radius`, else None; the walk stops where the map ends. OffMapError when the map cannot place `pose`."""
    point, heading = smap.lane_point(pose, lane)
    tightest = 0.0
    for _ in range(int(NEAR_RANGE / WALK_STEP) + 1):
        here = Pose(float(point[0]), float(point[1]), heading)
        tightest = max(tightest, abs(float(smap.lane_curvature(here, lane))))
        ahead = Pose(here.x + WALK_STEP * math.cos(heading), here.y + WALK_STEP * math.sin(heading), heading)
        try:
            point, heading = smap.lane_point(ahead, lane)
        except OffMapError:
            break
    return 1.0 / tightest if tightest * radius > 1.0 else None


def followable(ld: LaneDetection, smap: SemanticMap, pose: Pose, lane: int,
               radius: float) -> tuple[LaneDetection, float | None]:
    """`ld` without its lines where the lane turns tighter than `radius` within `NEAR_RANGE` of `pose`, with that
    radius; `ld` itself and None elsewhere (or when it has no line). OffMapError when the map cannot place `pose`."""
    if ld.left is None and ld.right is None:
        return ld, None
    turn = tight_turn(smap, pose, lane, radius)
    if turn is None:
        return ld, None
    return dataclasses.replace(ld, left=None, right=None, left_prob=0.0, right_prob=0.0, left_var=None,
                               right_var=None), turn
