"""The chassis port of the simulated car: commands go straight to the PyBullet vehicle, time is physics steps."""

from __future__ import annotations

import math

from testbed.chassis import ChassisCommand, ChassisModel, ChassisPort, ChassisState, bicycle_yaw_rate
from testbed.world import PhysicsWorld


class DirectChassis(ChassisPort):
    """Drives the PyBullet vehicle of a `PhysicsWorld`; advance() steps physics to the next control instant.

    With `hold_s` > 0 commands are applied sample-and-hold the way the CAN chassis applies them: at the
    start of advance(), the latest command is applied only when t >= the next due instant, which then
    moves to the next multiple of `hold_s` after t. So a direct run and a CAN run see the same timing.
    `model` is what the chassis reports (`ChassisModel`: its yaw rate, its steering sensor's offset). Reporting the
    body's yaw rate, it also reports that rate averaged over the last advance (an integrating gyro's delta angle).
    Without `steer_sensor` the port reads no road-wheel angle and its states report it as NaN (a PyBullet state read
    less a tick, for a loop that uses none; a yaw rate derived from the steering needs the sensor).
    """

    def __init__(self, world: PhysicsWorld, hold_s: float = 0.0, model: ChassisModel | None = None,
                 steer_sensor: bool = True) -> None:
        model = model if model is not None else ChassisModel()
        if model.yaw_rate == "steering" and not steer_sensor:
            raise ValueError("a yaw rate derived from the steering angle needs the steering sensor")
        self.steer_sensor = steer_sensor
        self.world = world
        self.vehicle = world.vehicle
        self.hold_s = hold_s
        self.steer_offset = math.radians(model.steer_offset_deg)
        self.wheelbase = world.vehicle.params.wheelbase if model.yaw_rate == "steering" else None
        """The wheelbase the yaw rate is derived with (m); None: the body's yaw rate is reported."""
        self._next_due = 0.0
        self._steps = 0
        self._t_target = 0.0
        self._pending: ChassisCommand | None = None
        self._applied = ChassisCommand(0.0, 0.0)
        self._mean_yaw_rate: float | None = None
        """The body's yaw rate averaged over the last advance (rad/s); None before the first."""

    @property
    def t(self) -> float:
        """Control time: the sum of the advance() steps (what a chassis reports), not the physics grid."""
        return round(self._t_target, 9)

    def read(self) -> ChassisState:
        """The state the vehicle sensed at the end of the last advance (read afresh before the first one)."""
        v = self.vehicle
        sensed = v.sensed
        if sensed is None:
            pose, speed, yaw_rate = v.kinematics()
            sensed = (pose, speed, yaw_rate, v.steer_angle() if self.steer_sensor else math.nan)
        pose, speed, yaw_rate, steer = sensed
        if self.steer_offset:
            steer += self.steer_offset
        if self.wheelbase is not None:
            return ChassisState(t=self.t, speed=speed, steer=steer, accel=v.accel(), true_pose=pose,
                                yaw_rate=bicycle_yaw_rate(speed, steer, self.wheelbase), true_yaw_rate=yaw_rate)
        return ChassisState(t=self.t, speed=speed, steer=steer, accel=v.accel(), true_pose=pose, yaw_rate=yaw_rate,
                            mean_yaw_rate=self._mean_yaw_rate)

    def send(self, cmd: ChassisCommand) -> None:
        self._pending = cmd

    def _apply_due_command(self) -> None:
        if self._pending is None:
            return
        t = self._t_target
        if self.hold_s > 0:
            if t < self._next_due - 1e-9:
                return
            self._next_due = (math.floor(t / self.hold_s + 1e-9) + 1) * self.hold_s
        self._applied = self._pending
        self.vehicle.apply(self._applied.steer - self.steer_offset, self._applied.accel)

    def advance(self, dt: float) -> None:
        """Hand the applied command to the vehicle once, step physics to the next control instant, sense."""
        self._apply_due_command()
        self._t_target += dt
        steps = round(self._t_target / self.world.dt) - self._steps
        if steps <= 0:
            return
        interval = steps * self.world.dt
        v = self.vehicle
        yaw = v.sensed[0].yaw if v.sensed is not None else v.pose().yaw
        v.actuate(interval)
        for _ in range(steps):
            self.world.step()
        self._steps += steps
        v.sense(interval, self.steer_sensor)
        self._mean_yaw_rate = math.remainder(v.sensed[0].yaw - yaw, math.tau) / interval
