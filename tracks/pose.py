"""A planar pose in the world frame (x east, y north, yaw counter-clockwise from +x, radians)."""

from __future__ import annotations

import math
from typing import NamedTuple


def wrap_angle(a: float) -> float:
    """The angle `a` (rad) wrapped into [-π, π)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class Pose(NamedTuple):
    """Vehicle reference point (centre of the footprint on the ground) and heading."""

    x: float
    y: float
    yaw: float

    def is_finite(self) -> bool:
        return math.isfinite(self.x) and math.isfinite(self.y) and math.isfinite(self.yaw)

    def to_local(self, x: float, y: float) -> tuple[float, float]:
        """World point -> this pose's frame (x forward, y left)."""
        dx, dy = x - self.x, y - self.y
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return c * dx + s * dy, -s * dx + c * dy

    def to_world(self, x: float, y: float) -> tuple[float, float]:
        """Point in this pose's frame -> world."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return self.x + c * x - s * y, self.y + s * x + c * y
