"""The simulated vehicle pose in HIL, advanced from what the chassis reports: kinematic-bicycle odometry.

The rear axle moves along its heading at the reported speed v (the longitudinal speed of the rigid body) and
turns at ψ̇ = v tan δ / L from the reported road-wheel angle δ, or at the reported yaw rate where the profile
carries one. Each update integrates one interval exactly on the arc of constant v and ψ̇, with v the mean of
the speeds reported at its ends. The pose is that of the reference point `ref_ahead` m ahead of the rear axle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tracks.pose import Pose


@dataclass(frozen=True)
class OdometryGeometry:
    """Wheelbase L and the reference point's distance ahead of the rear axle (m)."""

    wheelbase: float = 2.7
    ref_ahead: float = 0.0


class KinematicOdometry:
    """Dead reckoning of the reference-point pose from reported speed and steering angle (or yaw rate)."""

    def __init__(self, start: Pose | None = None, geometry: OdometryGeometry = OdometryGeometry()) -> None:
        start = start or Pose(0.0, 0.0, 0.0)
        self.geometry = geometry
        self._yaw = start.yaw
        self._x = start.x - geometry.ref_ahead * math.cos(start.yaw)
        self._y = start.y - geometry.ref_ahead * math.sin(start.yaw)
        self._speed: float | None = None

    @property
    def pose(self) -> Pose:
        d = self.geometry.ref_ahead
        return Pose(self._x + d * math.cos(self._yaw), self._y + d * math.sin(self._yaw), self._yaw)

    @property
    def speed(self) -> float:
        return self._speed or 0.0

    def update(self, dt: float, speed: float, steer: float, yaw_rate: float | None = None) -> None:
        """Advance by `dt` s to the moment `speed` and `steer` (or `yaw_rate`) were reported."""
        v0 = speed if self._speed is None else self._speed
        self._speed = speed
        if dt <= 0:
            return
        v = 0.5 * (v0 + speed)
        omega = yaw_rate if yaw_rate is not None else v * math.tan(steer) / self.geometry.wheelbase
        turn = omega * dt
        if abs(turn) < 1e-9:
            self._x += v * dt * math.cos(self._yaw + 0.5 * turn)
            self._y += v * dt * math.sin(self._yaw + 0.5 * turn)
        else:
            radius = v / omega
            self._x += radius * (math.sin(self._yaw + turn) - math.sin(self._yaw))
            self._y -= radius * (math.cos(self._yaw + turn) - math.cos(self._yaw))
        self._yaw += turn
