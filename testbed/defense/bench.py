"""CPython cost of LD3's per-detection work: one detection update (Alg. 1 + Alg. 3) and one fusion
update (Alg. 2 + Alg. 4 plus the fused pose), each as median and p99 in µs, with the odometry sample that
the fail-closed default dead-reckons on.

Runs on `StraightRoadMap`, a minimal two-lane straight road along +x defined here, so it needs nothing
outside this package.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from testbed.defense.config import DefenseConfig
from testbed.defense.ld3 import Ld3Defense
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import LaneCoord, OffMapError
from tracks.pose import Pose


class StraightRoadMap:
    """`lanes` lanes of width `width` along +x; lane 0's centreline is y = 0, lane i's is y = i·width.
    A pose more than width/2 + `margin` (default width/2) from its lane, or not finite, is off the map;
    `intersections` are x intervals flagged by is_intersection."""

    def __init__(self, lanes: int = 2, width: float = 3.5, margin: float | None = None,
                 intersections: tuple[tuple[float, float], ...] = ()) -> None:
        self.lanes = lanes
        self.width = width
        self.margin = width / 2 if margin is None else margin
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


def _timings(call: Callable[[int], object], n: int) -> dict[str, float]:
    samples = np.empty(n)
    for i in range(n):
        t0 = time.perf_counter_ns()
        call(i)
        samples[i] = time.perf_counter_ns() - t0
    return {"median_us": float(np.median(samples)) / 1e3, "p99_us": float(np.percentile(samples, 99)) / 1e3}


def _inputs(i: int) -> tuple[LaneDetection, LocalizationEstimate]:
    """A drive along lane 0 with a slow sinusoidal weave seen consistently by MSF and LD."""
    t = i * 0.05
    dev = 0.2 * math.sin(0.5 * t)
    left = np.array([1.75 - dev, 0.0, 0.0, 0.0])
    right = np.array([-1.75 - dev, 0.0, 0.0, 0.0])
    ld = LaneDetection(t, left, right, 0.9, 0.9, (0.0, 50.0))
    return ld, LocalizationEstimate(t, Pose(10.0 * t, dev, 0.0), np.eye(3) * 0.01)


def _odometry(defense: Ld3Defense, msf: LocalizationEstimate) -> None:
    """The odometry sample of `_inputs`' drive (10 m/s along +x) at the detection's time."""
    defense.on_odometry(msf.t, 10.0, 0.0)


def detection_update_benchmark(n: int = 5000) -> dict[str, float]:
    """One `Ld3Defense.on_lane_detection` in normal mode (map queries, Alg. 3, CUSUM, the odometry anchor)."""
    smap = StraightRoadMap()
    defense = Ld3Defense(DefenseConfig())
    inputs = [_inputs(i) for i in range(n)]

    def step(i: int) -> None:
        _odometry(defense, inputs[i][1])
        defense.on_lane_detection(*inputs[i], smap)

    return _timings(step, n)


def fusion_update_benchmark(n: int = 5000) -> dict[str, float]:
    """One attack-response step: `on_lane_detection` in AR (deviations + Alg. 4 + Alg. 2) and the
    `pose_for_control` that places the fused deviation on the lane."""
    smap = StraightRoadMap()
    defense = Ld3Defense(DefenseConfig())
    ld, msf = _inputs(0)
    # MSF 1 m left of what LD sees: S grows by 1 − b a detection until it passes τ and AR starts.
    for _ in range(1000):
        if defense.mode == "ar":
            break
        defense.on_lane_detection(ld, LocalizationEstimate(0.0, Pose(0.0, 1.0, 0.0), msf.cov), smap)
    if defense.mode != "ar":
        raise RuntimeError("fusion bench: the seeding detection did not start attack response")
    inputs = [_inputs(i) for i in range(1, n + 1)]

    def step(i: int) -> None:
        ld_i, msf_i = inputs[i]
        _odometry(defense, msf_i)
        defense.on_lane_detection(ld_i, msf_i, smap)
        defense.pose_for_control(msf_i, smap)

    return _timings(step, n)


if __name__ == "__main__":
    print("detection update:", detection_update_benchmark())
    print("fusion update:", fusion_update_benchmark())
