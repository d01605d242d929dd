"""A bare PyBullet world for vehicle tests: DIRECT client, 240 Hz, gravity, infinite flat ground (μ = 1)."""

from __future__ import annotations

from collections.abc import Callable

import pybullet as p

from vehicles.pybullet_vehicle import PyBulletVehicle

DT = 1.0 / 240.0


def make_world(solver_iterations: int | None = None) -> int:
    cid = p.connect(p.DIRECT)
    p.setGravity(0.0, 0.0, -9.81, physicsClientId=cid)
    p.setTimeStep(DT, physicsClientId=cid)
    if solver_iterations is not None:
        p.setPhysicsEngineParameter(numSolverIterations=solver_iterations, physicsClientId=cid)
    ground = p.createMultiBody(
        0.0, p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid), physicsClientId=cid
    )
    p.changeDynamics(ground, -1, lateralFriction=1.0, physicsClientId=cid)
    return cid


def drive(
    cid: int,
    vehicle: PyBulletVehicle,
    seconds: float,
    controller: Callable[[], tuple[float, float]],
    on_step: Callable[[], None] | None = None,
) -> None:
    """Step the world for `seconds`, asking `controller` for (steer, accel) before every physics step."""
    for _ in range(round(seconds / DT)):
        vehicle.apply(*controller())
        vehicle.actuate(DT)
        vehicle.apply_road_load()
        p.stepSimulation(physicsClientId=cid)
        vehicle.sense(DT)
        if on_step is not None:
            on_step()


def speed_controller(
    vehicle: PyBulletVehicle, target: float, steer: float = 0.0
) -> Callable[[], tuple[float, float]]:
    """Proportional speed control (1 s⁻¹) at a constant steering angle."""
    return lambda: (steer, 1.0 * (target - vehicle.speed()))


def drive_at_rate(
    cid: int,
    vehicle: PyBulletVehicle,
    seconds: float,
    controller: Callable[[], tuple[float, float]],
    command_hz: float,
    on_interval: Callable[[], None] | None = None,
) -> None:
    """Step the world for `seconds` with a command from `controller` every 1/`command_hz` s, actuated once
    for the physics steps up to the next command (2 or 3 of them at 100 Hz), as the direct chassis does;
    `on_interval` is called at the end of each command interval."""
    steps_done = 0
    for k in range(1, round(seconds * command_hz) + 1):
        steps = round(k / command_hz / DT) - steps_done
        vehicle.apply(*controller())
        vehicle.actuate(steps * DT)
        for _ in range(steps):
            vehicle.apply_road_load()
            p.stepSimulation(physicsClientId=cid)
        vehicle.sense(steps * DT)
        steps_done += steps
        if on_interval is not None:
            on_interval()
