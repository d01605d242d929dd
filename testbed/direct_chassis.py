"""The chassis port of the simulated car: commands go straight to the PyBullet vehicle, time is physics steps."""

from __future__ import annotations

from testbed.chassis import ChassisCommand, ChassisPort, ChassisState
from testbed.world import PhysicsWorld


class DirectChassis(ChassisPort):
    """Drives the PyBullet vehicle of a `PhysicsWorld`; advance() steps physics to the next control instant.

    `hold_s` > 0 applies commands sample-and-hold at that period (the CAN chassis applies them at 50 Hz),
    so a direct run and a CAN run see the same command timing.
    """

    def __init__(self, world: PhysicsWorld, hold_s: float = 0.0) -> None:
        self.world = world
        self.vehicle = world.vehicle
        self.hold_steps = max(1, round(hold_s / world.dt)) if hold_s > 0 else 1
        self._steps = 0
        self._t_target = 0.0
        self._pending: ChassisCommand | None = None
        self._applied = ChassisCommand(0.0, 0.0)

    def read(self) -> ChassisState:
        v = self.vehicle
        return ChassisState(t=self._steps * self.world.dt, speed=v.speed(), steer=v.steer_angle(), accel=v.accel(),
                            true_pose=v.pose(), yaw_rate=v.yaw_rate())

    def send(self, cmd: ChassisCommand) -> None:
        self._pending = cmd

    @property
    def applied(self) -> ChassisCommand:
        return self._applied

    def advance(self, dt: float) -> None:
        self._t_target += dt
        target = round(self._t_target / self.world.dt)
        while self._steps < target:
            if self._pending is not None and self._steps % self.hold_steps == 0:
                self._applied = self._pending
                self.vehicle.apply(self._applied.steer, self._applied.accel)
            self.world.step()
            self._steps += 1
