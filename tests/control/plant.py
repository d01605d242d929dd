"""Test-only vehicle plant: nonlinear dynamic bicycle (linear tyres saturating at μ·F_z) with actuator limits.

Steering: first-order lag then rate limit then angle limit; acceleration: first-order lag; kinematic
bicycle below 1.5 m/s (the dynamic one is singular at standstill). Integrated with 2 ms Euler steps.
The reported pose is the footprint centre, taken at mid-wheelbase.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tracks.pose import Pose

G = 9.81


@dataclass
class PlantParams:
    wheelbase: float = 2.85
    mass: float = 1800.0
    yaw_inertia: float = 3300.0
    lf: float = 1.35
    cf: float = 1.2e5
    cr: float = 1.5e5
    mu: float = 0.9
    max_steer: float = 0.6
    steer_rate: float = 0.5
    steer_tau: float = 0.1
    accel_tau: float = 0.1
    kinematic_below: float = 1.5


class BicyclePlant:
    """State at the CG: position, yaw, body velocities (vx, vy), yaw rate r, actual steer and accel."""

    def __init__(self, p: PlantParams, pose: Pose, speed: float, substep: float = 0.002):
        self.p, self.h = p, substep
        off = p.wheelbase / 2.0 - (p.wheelbase - p.lf)  # CG ahead of the reference point
        self.x = pose.x + off * math.cos(pose.yaw)
        self.y = pose.y + off * math.sin(pose.yaw)
        self.yaw, self.vx, self.vy, self.r = pose.yaw, speed, 0.0, 0.0
        self.steer, self.accel = 0.0, 0.0

    def pose(self) -> Pose:
        off = self.p.wheelbase / 2.0 - (self.p.wheelbase - self.p.lf)
        return Pose(self.x - off * math.cos(self.yaw), self.y - off * math.sin(self.yaw), self.yaw)

    def step(self, steer_cmd: float, accel_cmd: float, dt: float) -> None:
        p, h = self.p, self.h
        lr = p.wheelbase - p.lf
        ff_max, fr_max = p.mu * p.mass * G * lr / p.wheelbase, p.mu * p.mass * G * p.lf / p.wheelbase
        for _ in range(round(dt / h)):
            rate = min(max((steer_cmd - self.steer) / p.steer_tau, -p.steer_rate), p.steer_rate)
            self.steer = min(max(self.steer + rate * h, -p.max_steer), p.max_steer)
            self.accel += (accel_cmd - self.accel) / p.accel_tau * h
            if self.vx < p.kinematic_below:
                self.r = self.vx * math.tan(self.steer) / p.wheelbase
                self.vy = lr * self.r
            else:
                alpha_f = self.steer - (self.vy + p.lf * self.r) / self.vx
                alpha_r = -(self.vy - lr * self.r) / self.vx
                fyf = min(max(p.cf * alpha_f, -ff_max), ff_max)
                fyr = min(max(p.cr * alpha_r, -fr_max), fr_max)
                self.vy += ((fyf * math.cos(self.steer) + fyr) / p.mass - self.vx * self.r) * h
                self.r += (p.lf * fyf * math.cos(self.steer) - lr * fyr) / p.yaw_inertia * h
            c, s = math.cos(self.yaw), math.sin(self.yaw)
            self.x += (self.vx * c - self.vy * s) * h
            self.y += (self.vx * s + self.vy * c) * h
            self.yaw += self.r * h
            self.vx = max(self.vx + self.accel * h, 0.0)
