"""Along-lane shift of the MSF pose: moved `along` m along the lane (+ ahead), ramped in over `ramp` s, with its
signed offset from the centreline and its heading relative to the lane kept. Neither lateral check sees it
(D_MSF and the relative heading are the true ones), yet it hands the controller another station's curvature
and, in the response, an anchor at the wrong place."""

from __future__ import annotations

import math
from typing import Any

from testbed.attacks.base import Attack, AttackerView, left_normal
from testbed.attacks.profile import check_finite, ramp_fraction
from testbed.attacks.threat import ThreatCapability
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import OffMapError, SemanticMap
from tracks.pose import Pose, wrap_angle

STEP_M = 5.0
"""Largest step along the lane between two projections onto it (m): short enough to follow a curve."""
IDLE, RAMPING, HELD = "idle", "ramping", "held"


def along_lane(pose: Pose, smap: SemanticMap, lane: int, along: float) -> Pose:
    """`pose` moved `along` m along `lane` in steps of at most `STEP_M`, keeping its signed offset from the
    centreline and its heading relative to the lane; the pose as far as the map reaches where it ends."""
    try:
        point, heading = smap.lane_point(pose, lane)
        offset = float(smap.lane_dev(pose, lane))
    except OffMapError:
        return pose
    relative = wrap_angle(pose.yaw - heading)
    steps = max(1, math.ceil(abs(along) / STEP_M))
    for _ in range(steps):
        probe = Pose(float(point[0]) + along / steps * math.cos(heading),
                     float(point[1]) + along / steps * math.sin(heading), heading)
        try:
            point, heading = smap.lane_point(probe, lane)
        except OffMapError:
            break
    n = left_normal(heading)
    return Pose(float(point[0]) + offset * float(n[0]), float(point[1]) + offset * float(n[1]),
                wrap_angle(heading + relative))


class AlongShift(Attack):
    """Shifts the MSF pose along the victim's lane (module docstring); `offset` in the state is the shift (m)."""

    name = "along"
    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(self, start: float = 10.0, along: float = 20.0, ramp: float = 2.0) -> None:
        super().__init__(start)
        check_finite("along shift", along)
        check_finite("along ramp", ramp, 0.0)
        self.along, self.ramp = along, ramp
        self.stage = IDLE
        self.offset = 0.0

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        k = ramp_fraction(view.t - self.start_time, self.ramp)
        self.stage = IDLE if k == 0.0 else (HELD if k >= 1.0 else RAMPING)
        self.offset = k * self.along
        if k == 0.0:
            return est
        if self.whitebox is None:
            raise RuntimeError("along attack used before know(): it needs the map")
        moved = along_lane(est.pose, self.whitebox.smap, self.whitebox.lane, self.offset)
        return LocalizationEstimate(est.t, moved, est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": None, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "along": self.along, "ramp": self.ramp}
