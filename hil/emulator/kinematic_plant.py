"""A kinematic-bicycle ChassisPort: the ECU emulator's stand-alone plant (bus bring-up, benchmarks, tests).

State (x, y, yaw, v, steer); the command's steer angle and acceleration act at once (no actuator lag);
ẋ = v cos ψ, ẏ = v sin ψ, ψ̇ = v tan δ / L, v̇ = a, integrated with explicit Euler at `substep` s; braking stops
at zero speed (no reverse).
"""

from __future__ import annotations

import math

from testbed.chassis import ChassisCommand, ChassisPort, ChassisState
from tracks.pose import Pose


class KinematicBicyclePlant(ChassisPort):
    """Kinematic bicycle with wheelbase `wheelbase` m, integrated in sub-steps of `substep` s."""

    def __init__(
        self, wheelbase: float = 2.7, substep: float = 1 / 240, pose: Pose | None = None, speed: float = 0.0
    ) -> None:
        self.wheelbase = wheelbase
        self.substep = substep
        self._t = 0.0
        self._x, self._y, self._yaw = pose if pose is not None else Pose(0.0, 0.0, 0.0)
        self._v = speed
        self._cmd = ChassisCommand(0.0, 0.0)
        self._accel = 0.0

    def read(self) -> ChassisState:
        return ChassisState(
            t=self._t,
            speed=self._v,
            steer=self._cmd.steer,
            accel=self._accel,
            true_pose=Pose(self._x, self._y, self._yaw),
            yaw_rate=self._v * math.tan(self._cmd.steer) / self.wheelbase,
        )

    def send(self, cmd: ChassisCommand) -> None:
        self._cmd = cmd

    def advance(self, dt: float) -> None:
        steps = max(1, round(dt / self.substep))
        h = dt / steps
        for _ in range(steps):
            v_next = max(self._v + self._cmd.accel * h, 0.0)
            self._accel = (v_next - self._v) / h
            yaw_rate = self._v * math.tan(self._cmd.steer) / self.wheelbase
            self._x += self._v * math.cos(self._yaw) * h
            self._y += self._v * math.sin(self._yaw) * h
            self._yaw += yaw_rate * h
            self._v = v_next
        self._t += dt
