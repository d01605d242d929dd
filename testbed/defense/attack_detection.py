"""LD3 attack detection (paper Alg. 1): per lane detection, D_MSF = map lane deviation of the latest MSF
pose, D_LD by Alg. 3 with the map's lane width, and a one-sided CUSUM on D_MSF − D_LD:
S_i = max(0, S_{i-1} + |r_i| − b), alarm when S_i > τ (lines 6–10).

Detection is disabled while the MSF pose is inside an intersection (no lane markings) and resumes after
it with S reset and Alg. 3's memory cleared. A detection with a non-finite pose, an off-map query, or no
D_LD yet is skipped and logged. `Ld3Detector` and `cusum_alarm_index` run the same test on logged
(D_MSF, D_LD) traces, e.g. to sweep b and τ for ROC curves.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from testbed.defense.faults import FaultLog
from testbed.defense.ld_deviation import LdDeviation
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import OffMapError, SemanticMap
from tracks.pose import Pose


class Cusum:
    """One-sided CUSUM over residual magnitudes; latches at the first alarm (Alg. 1 `break`)."""

    def __init__(self, b: float, tau: float) -> None:
        self.b = b
        self.tau = tau
        self.statistic = 0.0
        self.alarmed = False

    def update(self, residual: float) -> bool:
        """Feed one residual; True once S > τ. After the alarm S is frozen at its alarm value."""
        if not self.alarmed:
            self.statistic = max(0.0, self.statistic + abs(residual) - self.b)
            self.alarmed = self.statistic > self.tau
        return self.alarmed

    def reset(self) -> None:
        """S back to 0 and the alarm cleared (after a zone where detection is disabled)."""
        self.statistic = 0.0
        self.alarmed = False


def cusum_alarm_index(residuals: Iterable[float], b: float, tau: float) -> int | None:
    """Index of the first residual at which CUSUM(b, τ) alarms, or None: for offline (b, τ) sweeps."""
    s = 0.0
    for i, r in enumerate(residuals):
        s = max(0.0, s + abs(r) - b)
        if s > tau:
            return i
    return None


class Ld3Detector:
    """Consistency check between the MSF and LD lateral deviations; latches at the first alarm."""

    def __init__(self, b: float = 0.6, tau: float = 0.1) -> None:
        self.cusum = Cusum(b, tau)

    def update(self, d_msf: float, d_ld: float) -> bool:
        """Feed one pair of deviations (m); True once under attack."""
        return self.cusum.update(d_msf - d_ld)

    @property
    def statistic(self) -> float:
        return self.cusum.statistic

    @property
    def alarmed(self) -> bool:
        return self.cusum.alarmed

    def reset(self) -> None:
        self.cusum.reset()


class LaneConsistencyMonitor:
    """Alg. 1 with intersection gating. After the alarm, `ego_lane` is the lane the MSF pose was on at the last
    detection where D_MSF and D_LD agreed within b (the MSF lane at the alarm if they never did): an attacker
    can move the MSF pose farther than b from where the lines put the car only by raising the statistic, so
    that lane is the car's own even when the alarm comes on an MSF pose already beyond half a lane."""

    def __init__(self, b: float, tau: float, existence_threshold: float, faults: FaultLog) -> None:
        self.detector = Ld3Detector(b, tau)
        self.ld_dev = LdDeviation(existence_threshold)
        self.faults = faults
        self.d_msf: float | None = None
        self.d_ld: float | None = None
        self.in_intersection = False
        self.ego_lane: int | None = None
        self._agreed_lane: int | None = None

    def step(self, ld: LaneDetection, msf: LocalizationEstimate, smap: SemanticMap) -> bool:
        """One detection step; True at (and after) the alarm."""
        if self.detector.alarmed:
            return True
        pose = msf.pose
        if not pose.is_finite():
            self.faults.report("nan-pose", ld.timestamp, f"MSF pose {pose} is not finite; update skipped")
            return False
        try:
            inside = smap.is_intersection(pose)
        except OffMapError as err:
            self.faults.report("off-map", ld.timestamp, f"is_intersection: {err}; update skipped")
            return False
        if inside:
            self.in_intersection = True
            return False
        if self.in_intersection:
            self.in_intersection = False
            self.detector.reset()
            self.ld_dev.reset()
        pair = self.deviations(ld, pose, smap)
        if pair is None:
            return False
        try:
            lane = smap.project(pose).lane
        except OffMapError as err:
            self.faults.report("off-map", ld.timestamp, f"project: {err}; ego lane left to the map")
            lane = None
        if abs(pair[0] - pair[1]) <= self.detector.cusum.b and lane is not None:
            self._agreed_lane = lane
        if not self.detector.update(*pair):
            return False
        self.ego_lane = self._agreed_lane if self._agreed_lane is not None else lane
        return True

    def ego_pair(self, t: float, pose: Pose, smap: SemanticMap) -> tuple[float, float] | None:
        """The alarm's (D_MSF, D_LD) with D_MSF measured against `ego_lane` (Alg. 1 measured it against the
        lane nearest the MSF pose); None when the map cannot answer."""
        if self.d_msf is None or self.d_ld is None:
            return None
        try:
            return float(smap.lane_dev(pose, self.ego_lane)), self.d_ld
        except OffMapError as err:
            self.faults.report("off-map", t, f"lane_dev on the ego lane at the alarm: {err}")
            return None

    def deviations(
        self, ld: LaneDetection, pose: Pose, smap: SemanticMap, lane: int | None = None
    ) -> tuple[float, float] | None:
        """(D_MSF, D_LD) against `lane` (nearest lane when None), or None when it cannot be formed."""
        t = ld.timestamp
        if not pose.is_finite():
            self.faults.report("nan-pose", t, f"MSF pose {pose} is not finite; update skipped")
            return None
        try:
            d_msf = float(smap.lane_dev(pose, lane))
            width = float(smap.lane_width(pose, lane))
        except OffMapError as err:
            self.faults.report("off-map", t, f"lane_dev/lane_width: {err}; update skipped")
            return None
        if not (math.isfinite(d_msf) and math.isfinite(width) and width > 0.0):
            self.faults.report("bad-map", t, f"D_MSF={d_msf}, lane width={width}; update skipped")
            return None
        d_ld = self.ld_dev.update(ld, width)
        if d_ld is None:
            self.faults.report("no-lane-lines", t, "no valid lane line yet; update skipped")
            return None
        if self.ld_dev.reused:
            self.faults.report("no-lane-lines", t, f"no valid lane line; reusing D_LD={d_ld:.3f}")
        else:
            self.faults.clear()
        self.d_msf, self.d_ld = d_msf, d_ld
        return d_msf, d_ld
