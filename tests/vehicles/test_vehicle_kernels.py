"""The compiled actuation and sensing of the PyBullet vehicle command and sense to the bit as the pure-Python
methods do: two identical worlds, one car each, the same random commands (steering beyond its limits both ways,
full throttle to full braking, standing and rolling backwards), every motor command PyBullet receives and every
state sensed compared, for the sedan and the dev chassis."""

import struct

import numpy as np
import pybullet as p
import pytest

from tests.vehicles.flat_world import make_world
from tracks.compiled import compiled_module
from tracks.pose import Pose
from vehicles.params import DEV_CHASSIS, SEDAN
from vehicles.pybullet_vehicle import PyBulletVehicle

KERNELS = compiled_module("vehicles.vehicle_kernels")


def bits(values: object) -> object:
    """Floats as their bytes (0.0 and -0.0 differ), nested tuples and lists walked."""
    if isinstance(values, float):
        return struct.pack("<d", values)
    if isinstance(values, tuple | list):
        return [bits(v) for v in values]
    return values


def state(car: PyBulletVehicle) -> object:
    steering = car._steering
    return bits((car.sensed, car._accel, car._speed, car._load, car._sent_steer, steering.angle, steering.rate))


@pytest.mark.skipif(KERNELS is None, reason="the Cython kernels are not built (no C compiler at install)")
@pytest.mark.parametrize("params", [SEDAN, DEV_CHASSIS], ids=["sedan", "dev-chassis"])
def test_the_compiled_vehicle_commands_and_senses_as_the_python_one(params, monkeypatch):
    worlds = make_world(), make_world()
    try:
        fast, slow = (PyBulletVehicle(w, params, Pose(2.0, -1.0, 0.3)) for w in worlds)
        slow._motion = None
        assert fast._motion is not None
        sent: dict[int, list] = {w: [] for w in worlds}
        motors = p.setJointMotorControlArray

        def record(*args, **kwargs):
            client = kwargs["physicsClientId"]
            sent[client].append(bits((args, sorted((k, v) for k, v in kwargs.items() if k != "physicsClientId"))))
            return motors(*args, **kwargs)

        monkeypatch.setattr(p, "setJointMotorControlArray", record)
        rng = np.random.default_rng(5)
        for car in (fast, slow):
            car.reset_pose(Pose(2.0, -1.0, 0.3), speed=3.0)
        steer, accel = 0.0, 0.0
        for k in range(1200):
            if k % 30 == 0:
                steer = float(rng.uniform(-1.5, 1.5) * params.max_steer)
                accel = float(rng.choice([rng.uniform(-params.max_decel, params.max_accel + 1.0), 0.0, -8.0, 9.0]))
            interval = 2.0 / 240.0
            for car in (fast, slow):
                car.apply(steer, accel)
                car.actuate(interval)
            for _ in range(2):
                for car, w in zip((fast, slow), worlds, strict=True):
                    car.apply_road_load()
                    p.stepSimulation(physicsClientId=w)
            for car in (fast, slow):
                car.sense(interval, k % 3 != 0)  # every third interval without the road-wheel angle
            assert state(fast) == state(slow), k
            assert sent[worlds[0]] == sent[worlds[1]], k
        assert len(sent[worlds[0]]) > 1200  # every interval's command (the steering in it when it moved) and the resets
    finally:
        for w in worlds:
            p.disconnect(w)
