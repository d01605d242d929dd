"""Test-only SemanticMap: parallel lanes around a centreline built from a piecewise curvature profile.

Straight, circular and clothoid pieces are integrated into a dense polyline (0.1 m); projections are
exact onto its segments near the KD-tree's nearest vertex.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from tracks.map_api import LaneCoord, OffMapError
from tracks.pose import Pose

SAMPLE = 0.1


class PolylineLaneMap:
    """`n_lanes` lanes of `lane_width`, lane 0 on the reference centreline, higher lanes to its left."""

    def __init__(self, pieces: list[tuple[float, float, float]], n_lanes: int = 2, lane_width: float = 3.5):
        """`pieces`: (length, curvature at start, curvature at end); curvature varies linearly (clothoid)."""
        kappa = [pieces[0][1]]
        for length, k0, k1 in pieces:
            n = max(1, round(length / SAMPLE))
            kappa.extend(k0 + (k1 - k0) * (np.arange(1, n + 1) / n))
        self.kappa = np.array(kappa)
        heading = np.concatenate([[0.0], np.cumsum(0.5 * (self.kappa[1:] + self.kappa[:-1]) * SAMPLE)])
        mid = heading[:-1] + 0.5 * np.diff(heading)
        xy = np.zeros((len(self.kappa), 2))
        xy[1:, 0] = np.cumsum(np.cos(mid) * SAMPLE)
        xy[1:, 1] = np.cumsum(np.sin(mid) * SAMPLE)
        self.xy, self.heading = xy, heading
        self.s = np.arange(len(self.kappa)) * SAMPLE
        self.n_lanes, self.width = n_lanes, lane_width
        self.tree = cKDTree(xy)
        self._pts = xy.tolist()
        self._hint = 0

    def _nearest(self, x: float, y: float) -> int:
        """Nearest vertex: a local search around the last answer, the KD-tree when that is far off."""
        lo, hi = max(self._hint - 200, 0), min(self._hint + 200, len(self.s))
        d2 = (self.xy[lo:hi, 0] - x) ** 2 + (self.xy[lo:hi, 1] - y) ** 2
        k = int(np.argmin(d2))
        local = 0 < k < hi - lo - 1 and d2[k] < 100.0
        i = lo + k if local else int(self.tree.query((x, y))[1])
        self._hint = i
        return int(min(max(i, 1), len(self.s) - 2))

    def _centreline(self, x: float, y: float) -> tuple[float, float]:
        """Arc length and signed offset (+ left) of (x, y) from the reference centreline."""
        if not (math.isfinite(x) and math.isfinite(y)):
            raise OffMapError("pose is not finite")
        i = self._nearest(x, y)
        best = (math.inf, 0.0, 0.0)
        for j in (i - 1, i):
            x0, y0 = self._pts[j]
            dx, dy = self._pts[j + 1][0] - x0, self._pts[j + 1][1] - y0
            u = min(max(((x - x0) * dx + (y - y0) * dy) / (SAMPLE * SAMPLE), 0.0), 1.0)
            ex, ey = x - (x0 + u * dx), y - (y0 + u * dy)
            dist2 = ex * ex + ey * ey
            if dist2 < best[0]:
                side = dx * (y - y0) - dy * (x - x0)
                best = (dist2, j * SAMPLE + u * SAMPLE, math.copysign(math.sqrt(dist2), side))
        _, s, off = best
        if s <= 0.0 or s >= self.s[-1]:
            raise OffMapError("pose beyond the ends of the road")
        return s, off

    def project(self, pose: Pose, lane: int | None = None) -> LaneCoord:
        s, off = self._centreline(pose.x, pose.y)
        if lane is None:
            lane = round(off / self.width)
        if not 0 <= lane < self.n_lanes or abs(off - lane * self.width) > self.width:
            raise OffMapError("pose is not on the lane")
        return LaneCoord(lane, s, off - lane * self.width)

    def lane_dev(self, pose: Pose, lane: int | None = None) -> float:
        return self.project(pose, lane).l

    def lane_width(self, pose: Pose, lane: int | None = None) -> float:
        return self.width

    def _at(self, s: float) -> tuple[float, float, float, float]:
        i = min(int(s / SAMPLE), len(self.s) - 2)
        f = s / SAMPLE - i
        x, y = self.xy[i] + f * (self.xy[i + 1] - self.xy[i])
        h = self.heading[i] + f * (self.heading[i + 1] - self.heading[i])
        k = self.kappa[i] + f * (self.kappa[i + 1] - self.kappa[i])
        return float(x), float(y), float(h), float(k)

    def lane_point(self, pose: Pose, lane: int | None = None) -> tuple[np.ndarray, float]:
        coord = self.project(pose, lane)
        x, y, h, _ = self._at(coord.s)
        off = coord.lane * self.width
        return np.array([x - off * math.sin(h), y + off * math.cos(h)]), h

    def lane_curvature(self, pose: Pose, lane: int | None = None) -> float:
        coord = self.project(pose, lane)
        k = self._at(coord.s)[3]
        return k / (1.0 - coord.lane * self.width * k)

    def is_intersection(self, pose: Pose) -> bool:
        return False


def straight(length: float = 1000.0) -> PolylineLaneMap:
    return PolylineLaneMap([(length, 0.0, 0.0)])


def curvy_urban() -> PolylineLaneMap:
    """Straight, clothoid into a left R = 60 m arc, clothoid out, then the same to the right."""
    k = 1.0 / 60.0
    left = [(30, 0, k), (50, k, k), (30, k, 0)]
    right = [(30, 0, -k), (50, -k, -k), (30, -k, 0)]
    return PolylineLaneMap([(30, 0, 0), *left, (20, 0, 0), *right, (25, 0, 0)])


def highway() -> PolylineLaneMap:
    """Straight, clothoid into a left R = 600 m arc, an S-clothoid into a right one, back to straight."""
    k = 1.0 / 600.0
    arcs = [(100, 0, k), (150, k, k), (100, k, -k), (150, -k, -k), (100, -k, 0)]
    return PolylineLaneMap([(50, 0, 0), *arcs, (100, 0, 0)])
