"""The semantic map of a track (implements `tracks.map_api.SemanticMap`, paper Table 3).

A pose is projected once onto the track's reference line (local search from the previous answer, exact
Newton refinement), then expressed against the requested lane, or against the lane containing it (the
nearest lane centre when between or beyond lanes) when `lane` is None. On a two-way road, `lane` None looks
only among the lanes whose direction of travel is within 90° of the pose's heading (a car pushed over the
centre line is still on its own side's map, far left of its lane). Offsets l are + left in the answered lane's
direction of travel. Lanes with width profiles are measured against their centre and edges at the projection's
s.
"""

from __future__ import annotations

import math

import numpy as np

from tracks.compiled import compiled_module
from tracks.map_api import LaneCoord, OffMapError
from tracks.pose import Pose
from tracks.recent import RecentAnswers
from tracks.road import Track

OFF_MAP_MARGIN = 3.0  # m beyond a lane's half width that still counts as on that lane's map
_MEMO_SIZE = 8  # recent (pose, lane) answers kept: a control tick asks about the same pose several times
_KERNELS = compiled_module("tracks.map_kernels")


class TrackMap:
    """SemanticMap over one `Track`."""

    def __init__(self, track: Track) -> None:
        self.track = track
        self._lanes = track.lanes
        self._centres = [ln.offset for ln in track.lanes]
        self._bounds = [(ln.offset - 0.5 * ln.width, ln.offset + 0.5 * ln.width) for ln in track.lanes]
        self._profiled = any(ln.profiles is not None for ln in track.lanes)
        self._all_lanes = range(len(track.lanes))
        self._sides = self._directions(track)
        lo, hi = self._bounds[0][0], self._bounds[-1][1]
        for ln in track.lanes if self._profiled else ():
            centre, width = ln.profiles[0].v, ln.profiles[1].v
            lo, hi = min(lo, float(np.min(centre - 0.5 * width))), max(hi, float(np.max(centre + 0.5 * width)))
        self._reach = (lo - OFF_MAP_MARGIN, hi + OFF_MAP_MARGIN)
        self._length = track.length
        self._memo: RecentAnswers[tuple[Pose, int | None], LaneCoord] = RecentAnswers(_MEMO_SIZE)
        line = track.reference._kernel
        self.compiled = None if _KERNELS is None or line is None or self._profiled else _KERNELS.MapKernel(
            line, track.reference, track.name, self._length, self._reach, self._centres, self._bounds,
            [ln.direction for ln in self._lanes], self._sides is not None,
            len(self._sides[0]) if self._sides is not None else len(self._lanes), _MEMO_SIZE)
        """`project`, `lane_point` and `lane_curvature` with the memo, compiled (tracks/map_kernels.pyx), where
        built and the lanes' offsets and widths are constant; None: the pure-Python methods answer, the reference
        the kernel is tested equal to."""

    @staticmethod
    def _directions(track: Track) -> tuple[range, range] | None:
        """(lanes along, lanes against) the reference line on a two-way road; None on a one-way road."""
        n, against = len(track.lanes), track.oncoming
        return None if against == 0 else (range(n - against), range(n - against, n))

    def project(self, pose: Pose, lane: int | None = None) -> LaneCoord:
        """The pose on `lane` (default: the lane containing it); the last few answers are returned again for
        the same pose and lane, errors are not kept."""
        if self.compiled is not None:
            return self.compiled.project(pose, lane)
        found = self._memo.get((pose, lane))
        return found if found is not None else self._memo.keep((pose, lane), self._project(pose, lane))

    def _project(self, pose: Pose, lane: int | None) -> LaneCoord:
        if not pose.is_finite():
            raise OffMapError(f"non-finite pose {pose}")
        x, y = pose.x, pose.y
        s, t = self.track.reference.project(x, y)
        if not (0.0 <= s <= self._length and self._reach[0] <= t <= self._reach[1]):
            raise OffMapError(
                f"pose ({x:.2f}, {y:.2f}) is off the map of {self.track.name} (s={s:.1f}, t={t:.2f})"
            )
        if lane is not None and not 0 <= lane < len(self._lanes):
            raise ValueError(f"lane {lane} not on {self.track.name} (lanes 0..{len(self._lanes) - 1})")
        if self._profiled:
            centres = [ln.offset_at(s) for ln in self._lanes]
            bounds = [(c - 0.5 * ln.width_at(s), c + 0.5 * ln.width_at(s)) for c, ln in zip(centres, self._lanes,
                                                                                           strict=True)]
        else:
            centres, bounds = self._centres, self._bounds
        if lane is None:
            lane = self._lane_at(t, bounds, self._candidates(pose, s))
        return LaneCoord(lane, s, self._lanes[lane].direction * (t - centres[lane]))

    def _candidates(self, pose: Pose, s: float) -> range:
        """The lanes a pose may be matched to: those of its direction of travel on a two-way road."""
        if self._sides is None:
            return self._all_lanes
        along = math.cos(pose.yaw - self.track.reference.heading_at(s)) >= 0.0
        return self._sides[0] if along else self._sides[1]

    @staticmethod
    def _lane_at(t: float, bounds: list[tuple[float, float]], lanes: range) -> int:
        for i in lanes:
            lo, hi = bounds[i]
            if lo <= t < hi:
                return i
        return lanes[0] if t < bounds[lanes[0]][0] else lanes[-1]

    def lane_dev(self, pose: Pose, lane: int | None = None) -> float:
        return self.project(pose, lane).l

    def lane_width(self, pose: Pose, lane: int | None = None) -> float:
        c = self.project(pose, lane)
        return self._lanes[c.lane].width_at(c.s)

    def lane_point(self, pose: Pose, lane: int | None = None) -> tuple[np.ndarray, float]:
        if self.compiled is not None:
            x, y, heading = self.compiled.lane_point(pose, lane)
            return np.array((x, y)), heading
        c = self.project(pose, lane)
        x, y, heading = self._lanes[c.lane].centre_at(c.s)
        return np.array((x, y)), heading

    def lane_curvature(self, pose: Pose, lane: int | None = None) -> float:
        if self.compiled is not None:
            return self.compiled.lane_curvature(pose, lane)
        c = self.project(pose, lane)
        return self._lanes[c.lane].curvature_at(c.s)

    def is_intersection(self, pose: Pose) -> bool:
        return self.track.in_intersection(self.project(pose).s)
