"""Test-only synthetic lane scene: parallel lines along a straight or circular road, a kinematic car, and
detections fitted exactly from the geometry (optionally with noise on c0).

Lines are at lateral offsets `LINES` from the road centreline (+ left). With curvature κ > 0 the road is a
circle turning left, centre (0, 1/κ), starting at the origin heading +x.
"""

from __future__ import annotations

import math

import numpy as np

from testbed.lane_detection import LaneDetection

LANE_W = 3.5
LINES = (-1.75, 1.75, 5.25)  # the ego lane's right and left lines and the left lane's left line
X_FIT = np.linspace(0.0, 30.0, 31)


class Scene:
    """Car pose (x, y, yaw) in the world, driven at `speed` with `yaw_rate`; frames every `dt` seconds."""

    def __init__(self, curvature: float = 0.0, speed: float = 12.0, dt: float = 0.05, lateral: float = 0.0,
                 yaw: float = 0.0) -> None:
        self.k = curvature
        self.speed = speed
        self.dt = dt
        self.t = 0.0
        self.x, self.y, self.yaw = 0.0, lateral, yaw
        self.yaw_rate = speed * curvature

    def step(self, steps: int = 20) -> None:
        """Advance one frame interval (integrated in `steps` sub-steps at constant speed and yaw rate)."""
        h = self.dt / steps
        for _ in range(steps):
            self.x += self.speed * h * math.cos(self.yaw + 0.5 * self.yaw_rate * h)
            self.y += self.speed * h * math.sin(self.yaw + 0.5 * self.yaw_rate * h)
            self.yaw += self.yaw_rate * h
        self.t += self.dt

    def deviation(self) -> float:
        """Signed lateral offset of the car from the centreline of the lane between LINES[0] and LINES[1]."""
        if self.k == 0.0:
            return self.y
        r = 1.0 / self.k
        return math.copysign(abs(r) - math.hypot(self.x, self.y - r), self.k)

    def line_points(self, offset: float) -> tuple[np.ndarray, np.ndarray]:
        """Points of the line at `offset` ahead of the car, in the vehicle frame."""
        s0 = self.x if self.k == 0.0 else math.atan2(self.k * self.x, 1.0 - self.k * self.y) / self.k
        s = s0 + np.linspace(-5.0, 40.0, 200)
        if self.k == 0.0:
            px, py = s, np.full_like(s, offset)
        else:
            r = 1.0 / self.k
            px, py = (r - offset) * np.sin(self.k * s), r - (r - offset) * np.cos(self.k * s)
        c, sn = math.cos(self.yaw), math.sin(self.yaw)
        return c * (px - self.x) + sn * (py - self.y), -sn * (px - self.x) + c * (py - self.y)

    def cubic(self, offset: float) -> np.ndarray:
        xv, yv = self.line_points(offset)
        keep = (xv >= -2.0) & (xv <= 32.0)
        return np.polynomial.polynomial.polyfit(xv[keep], yv[keep], 3)

    def detect(self, rng: np.random.Generator | None = None, noise: float = 0.0, left: bool = True,
               right: bool = True) -> LaneDetection:
        """The ego lines as a detector labels them (left: nearest line with c0 > 0, right: nearest with c0 <= 0),
        c0 perturbed by N(0, noise²); `left` / `right` False drops that line."""
        cubics = sorted((self.cubic(o) for o in LINES), key=lambda c: c[0])
        lft = next((c for c in cubics if c[0] > 0.0), None)
        rgt = next((c for c in reversed(cubics) if c[0] <= 0.0), None)
        out = []
        for c, keep in ((lft, left), (rgt, right)):
            if c is not None and keep:
                c = c.copy()
                if rng is not None and noise > 0.0:
                    c[0] += rng.normal(0.0, noise)
            out.append(c if keep else None)
        return LaneDetection(self.t, out[0], out[1], 1.0 if out[0] is not None else 0.0,
                             1.0 if out[1] is not None else 0.0, (0.0, 30.0))


class CurveEntry:
    """A straight that runs into an arc of radius `radius` turning left at `entry` m (no clothoid, as public maps often
    draw it), the car on the lane centre at `speed`; frames every `dt` seconds from `start` m."""

    def __init__(self, radius: float = 60.0, entry: float = 60.0, start: float = 20.0, speed: float = 12.0,
                 dt: float = 0.05) -> None:
        self.radius, self.entry, self.speed, self.dt = radius, entry, speed, dt
        self.s, self.t = start, 0.0

    @property
    def yaw_rate(self) -> float:
        return self.speed / self.radius if self.s >= self.entry else 0.0

    def _road(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        heading = np.where(s < self.entry, 0.0, (s - self.entry) / self.radius)
        x = np.where(s < self.entry, s, self.entry + self.radius * np.sin(heading))
        y = np.where(s < self.entry, 0.0, self.radius - self.radius * np.cos(heading))
        return x, y, heading

    def detect(self) -> LaneDetection:
        """Both ego lines, each a cubic fitted to it in the vehicle frame over x in [−2, 32] m."""
        cx, cy, ch = (float(v) for v in self._road(np.array(self.s)))
        x, y, heading = self._road(self.s + np.linspace(-5.0, 45.0, 400))
        cubics = []
        for offset in (LANE_W / 2, -LANE_W / 2):
            px, py = x - offset * np.sin(heading), y + offset * np.cos(heading)
            vx = math.cos(ch) * (px - cx) + math.sin(ch) * (py - cy)
            vy = -math.sin(ch) * (px - cx) + math.cos(ch) * (py - cy)
            keep = (vx >= -2.0) & (vx <= 32.0)
            cubics.append(np.polynomial.polynomial.polyfit(vx[keep], vy[keep], 3))
        return LaneDetection(self.t, cubics[0], cubics[1], 1.0, 1.0, (0.0, 30.0))

    def step(self) -> None:
        self.s += self.speed * self.dt
        self.t += self.dt
