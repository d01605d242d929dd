"""Steering: a rate- and angle-limited actuator, and Ackermann geometry between the bicycle-model
road-wheel angle δ and the two front wheel angles (cot δ_left = cot δ − t/2L, cot δ_right = cot δ + t/2L).
"""

from __future__ import annotations

import math


def ackermann_angles(delta: float, wheelbase: float, track: float) -> tuple[float, float]:
    """Left and right front wheel angles (rad, + left) for a bicycle-model angle `delta`."""
    t = math.tan(delta)
    half = track / 2.0
    left = math.atan2(wheelbase * t, wheelbase - half * t)
    right = math.atan2(wheelbase * t, wheelbase + half * t)
    return left, right


def bicycle_angle(left: float, right: float) -> float:
    """Bicycle-model angle equivalent to the two front wheel angles (mean of their cotangents)."""
    tl, tr = math.tan(left), math.tan(right)
    if tl + tr == 0.0:
        return 0.0
    return math.atan(2.0 * tl * tr / (tl + tr))


class SteeringActuator:
    """Road-wheel angle that moves towards its command at no more than `max_rate`, within ±`max_angle`."""

    def __init__(self, max_angle: float, max_rate: float) -> None:
        self.max_angle = max_angle
        self.max_rate = max_rate
        self.angle = 0.0
        self.rate = 0.0

    def reset(self, angle: float = 0.0) -> None:
        self.angle = max(-self.max_angle, min(self.max_angle, angle))
        self.rate = 0.0

    def step(self, command: float, dt: float) -> float:
        """Advance by `dt` towards `command`; return the new angle."""
        target = max(-self.max_angle, min(self.max_angle, command))
        max_step = self.max_rate * dt
        delta = max(-max_step, min(max_step, target - self.angle))
        self.angle += delta
        self.rate = delta / dt
        return self.angle
