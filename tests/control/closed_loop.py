"""Test-only closed loop: plant → noisy pose → LanePlanner → LQR steer + PI speed → plant, at 100 Hz."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache

import numpy as np

from testbed.control.lateral import LqrLateralController
from testbed.control.lateral_model import LateralModel
from testbed.control.longitudinal import SpeedController
from testbed.control.planner import LanePlanner
from tests.control.lane_map import PolylineLaneMap
from tests.control.plant import BicyclePlant, PlantParams
from tracks.pose import Pose

DT = 0.01


@dataclass
class Trace:
    t: list[float] = field(default_factory=list)
    dev: list[float] = field(default_factory=list)
    speed: list[float] = field(default_factory=list)
    steer: list[float] = field(default_factory=list)
    accel: list[float] = field(default_factory=list)

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(v) for k, v in self.__dict__.items()}


def controller_model() -> LateralModel:
    """What the controller believes (the plant differs: CG position, inertia, stiffnesses)."""
    return LateralModel.from_geometry(2.85, 1800.0)


@cache
def shared_lateral() -> LqrLateralController:
    """One controller for all runs (its gain schedule takes a fraction of a second to build)."""
    return LqrLateralController(controller_model(), PlantParams().max_steer, DT)


def drive(
    smap: PolylineLaneMap,
    speed: float,
    duration: float,
    rng: np.random.Generator,
    offset: float = 0.0,
    pose_noise: float = 0.02,
    yaw_noise: float = 0.002,
    on_tick: Callable[[float, LanePlanner, BicyclePlant], None] | None = None,
    plant_params: PlantParams | None = None,
    gyro: bool = True,
    start_speed: float | None = None,
) -> Trace:
    """Drive lane 0 from s = 5 m at cruise `speed` (starting at `start_speed`, default the same) and
    `offset` m left of the centreline; `gyro` passes the plant's yaw rate to the lateral controller
    (else it estimates it from its last command). `on_tick` may act on the planner (start a stop)."""
    pp = plant_params or PlantParams()
    start_speed = speed if start_speed is None else start_speed
    plant = BicyclePlant(pp, Pose(smap.xy[50, 0], smap.xy[50, 1] + offset, 0.0), start_speed)
    planner = LanePlanner(smap, 0, speed)
    lateral = shared_lateral()
    lateral.reset()
    longitudinal = SpeedController()
    trace = Trace()
    for i in range(round(duration / DT)):
        t = i * DT
        true = plant.pose()
        ex, ey, eyaw = rng.normal(0.0, (pose_noise, pose_noise, yaw_noise))
        noisy = Pose(true.x + ex, true.y + ey, true.yaw + eyaw)
        if on_tick is not None:
            on_tick(t, planner, plant)
        plan = planner.plan(noisy, plant.vx, t)
        steer = lateral.update(plan, plant.vx, yaw_rate=plant.r if gyro else None)
        accel = longitudinal.update(plan, plant.vx, DT)
        trace.t.append(t)
        trace.dev.append(smap.lane_dev(true, 0))
        trace.speed.append(plant.vx)
        trace.steer.append(plant.steer)
        trace.accel.append(plant.accel)
        plant.step(steer, accel, DT)
    return trace
