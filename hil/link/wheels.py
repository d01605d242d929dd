"""Rear-wheel geometry for wheel-speed reports: track width and rolling radius turn the rear wheels' rpm into
the axle's speed and the yaw rate, ψ̇ = (v_rr − v_rl) / track (rear wheels do not steer), and back."""

from __future__ import annotations

import math
from dataclasses import dataclass

from vehicles.params import VehicleParams


@dataclass(frozen=True)
class WheelGeometry:
    """Rear track width (m) and wheel rolling radius (m)."""

    track_m: float
    radius_m: float

    @classmethod
    def of(cls, params: VehicleParams) -> WheelGeometry:
        return cls(params.track_width, params.wheel_radius)

    def rpm(self, speed: float) -> float:
        """Wheel rpm at ground speed `speed` (m/s, + forward)."""
        return speed * 60.0 / (math.tau * self.radius_m)

    def speed(self, rpm: float) -> float:
        """Ground speed (m/s) of a wheel at `rpm`."""
        return rpm * math.tau * self.radius_m / 60.0

    def rear_rpm(self, speed: float, yaw_rate: float) -> tuple[float, float]:
        """(left, right) rear-wheel rpm of an axle at `speed` turning at `yaw_rate` (rad/s, + left)."""
        half = 0.5 * self.track_m * yaw_rate
        return self.rpm(speed - half), self.rpm(speed + half)

    def yaw_rate(self, rpm_left: float, rpm_right: float) -> float:
        """The yaw rate (rad/s, + left) of an axle whose rear wheels turn at these rpm."""
        return (self.speed(rpm_right) - self.speed(rpm_left)) / self.track_m
