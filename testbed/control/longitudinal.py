"""PI speed controller with target-acceleration feed-forward, conditional-integration anti-windup and a
standstill brake hold: a = a_target + kp·(v_t − v) + ki·∫(v_t − v) dt, clamped to [−max_decel, max_accel]."""

from __future__ import annotations

from testbed.control.plan import Plan


class SpeedController:
    """Acceleration command (m/s², < 0 brakes) tracking the plan's speed profile."""

    def __init__(
        self,
        kp: float = 0.8,
        ki: float = 0.3,
        max_accel: float = 3.0,
        max_decel: float = 8.0,
        integral_limit: float = 1.0,
        stop_speed: float = 0.1,
        hold_brake: float = 2.0,
    ) -> None:
        self.kp = kp
        self.ki = ki
        self.max_accel = max_accel
        self.max_decel = max_decel
        self.integral_limit = integral_limit
        self.stop_speed = stop_speed
        self.hold_brake = hold_brake
        self._integral = 0.0

    def reset(self) -> None:
        self._integral = 0.0

    def update(self, plan: Plan, speed: float, dt: float) -> float:
        if plan.target_speed <= 0.0 and speed < self.stop_speed:
            self._integral = 0.0
            return -min(self.hold_brake, self.max_decel)
        error = plan.target_speed - speed
        unclamped = plan.target_accel + self.kp * error + self._integral
        saturated_high = unclamped > self.max_accel and error > 0.0
        saturated_low = unclamped < -self.max_decel and error < 0.0
        if not (saturated_high or saturated_low):
            limit = self.integral_limit
            self._integral = min(max(self._integral + self.ki * error * dt, -limit), limit)
        accel = plan.target_accel + self.kp * error + self._integral
        return min(max(accel, -self.max_decel), self.max_accel)
