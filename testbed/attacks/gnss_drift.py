"""Adaptive GNSS drift: a white-box spoofer who waits for a stretch where the LiDAR locator is weak (the map's
feature profile, `lidar_below`), then drifts the GNSS fixes sideways at `rate` m/s up to `limit` m — slow
enough for the MSF's innovation gating to accept every fix, so the fused pose follows."""

from __future__ import annotations

import dataclasses
from typing import Any

from testbed.attacks.base import Attack, AttackerView, left_normal
from testbed.attacks.profile import check_finite, side_sign
from testbed.attacks.threat import ThreatCapability
from testbed.localization.sensors import GnssFix

IDLE, WAITING, DRIFTING = "idle", "waiting", "drifting"


class GnssDrift(Attack):
    """Linear lateral GNSS drift from the first moment after `start` that the LiDAR quality is below the mark."""

    name = "gnss-drift"
    capabilities = frozenset({ThreatCapability.GNSS})

    def __init__(self, start: float = 10.0, rate: float = 0.3, limit: float = 3.0, lidar_below: float = 1.01,
                 direction: str = "left") -> None:
        super().__init__(start)
        check_finite("gnss-drift rate", rate, 0.0)
        check_finite("gnss-drift limit", limit, 0.0)
        check_finite("gnss-drift lidar_below", lidar_below, 0.0)
        self.rate, self.limit, self.lidar_below = rate, limit, lidar_below
        self.direction, self.sign = direction, side_sign(direction, "gnss-drift")
        self.stage = IDLE
        self.offset = 0.0
        self._began: float | None = None

    def spoof_gnss(self, fix: GnssFix, view: AttackerView) -> GnssFix:
        if view.t < self.start_time:
            return fix
        if self._began is None:
            self.stage = WAITING
            quality = self.whitebox.lidar_quality if self.whitebox is not None else (lambda x, y: 0.0)
            if quality(view.true_pose.x, view.true_pose.y) >= self.lidar_below:
                return fix
            self._began = view.t
            self.stage = DRIFTING
        self.offset = self.sign * min(self.limit, self.rate * (view.t - self._began))
        return dataclasses.replace(fix, xy=fix.xy + self.offset * left_normal(view.lane_heading))

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": self._began, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "rate": self.rate, "limit": self.limit,
                "lidar_below": self.lidar_below, "direction": self.direction}
