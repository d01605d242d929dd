"""A steering change sent with the wheels' command in one PyBullet call (`PyBulletVehicle._send_all`) leaves the
car as the two calls it replaces do, to the bit: twin worlds, the same random commands (steering both ways,
driving and braking), every base and joint state compared after every interval."""

import struct

import numpy as np
import pybullet as p
import pytest

from tests.vehicles.flat_world import make_world
from tracks.pose import Pose
from vehicles.params import DEV_CHASSIS, SEDAN
from vehicles.pybullet_vehicle import PyBulletVehicle


def _bits(values: object) -> object:
    if isinstance(values, float):
        return struct.pack("<d", values)
    if isinstance(values, tuple | list):
        return [_bits(v) for v in values]
    return values


def _state(car: PyBulletVehicle, cid: int) -> object:
    joints = range(p.getNumJoints(car.body_id, physicsClientId=cid))
    return _bits((p.getBasePositionAndOrientation(car.body_id, physicsClientId=cid),
                  p.getBaseVelocity(car.body_id, physicsClientId=cid),
                  [s[:2] for s in p.getJointStates(car.body_id, joints, physicsClientId=cid)]))


def _two_calls(car: PyBulletVehicle):
    """`_send_all` as the steering's position call followed by the wheels' velocity call."""
    def send(delta: float, targets: tuple[float, ...], torques: tuple[float, ...]) -> None:
        car._send_steer(delta)
        p.setJointMotorControlArray(car.body_id, car.wheel_link_ids, p.VELOCITY_CONTROL, targetVelocities=targets,
                                    forces=torques, physicsClientId=car._cid)
    return send


@pytest.mark.parametrize("params", [SEDAN, DEV_CHASSIS], ids=["sedan", "dev-chassis"])
def test_one_motor_call_leaves_the_car_as_two_do(params):
    worlds = make_world(), make_world()
    try:
        one, two = (PyBulletVehicle(w, params, Pose(2.0, -1.0, 0.3)) for w in worlds)
        for car in (one, two):
            car._motion = None
            car.reset_pose(Pose(2.0, -1.0, 0.3), speed=3.0)
        two._send_all = _two_calls(two)
        rng = np.random.default_rng(11)
        steer, accel = 0.0, 0.0
        for k in range(900):
            if k % 25 == 0:
                steer = float(rng.uniform(-1.5, 1.5) * params.max_steer)
                accel = float(rng.choice([rng.uniform(-params.max_decel, params.max_accel), 0.0, -8.0]))
            for car in (one, two):
                car.apply(steer, accel)
                car.actuate(2.0 / 240.0)
            for _ in range(2):
                for car, w in zip((one, two), worlds, strict=True):
                    car.apply_road_load()
                    p.stepSimulation(physicsClientId=w)
            for car in (one, two):
                car.sense(2.0 / 240.0)
            assert _state(one, worlds[0]) == _state(two, worlds[1]), k
        assert one.speed() > 0.5 or one.speed() < -0.5 or abs(one.steer_angle()) > 0.01  # it moved and steered
    finally:
        for w in worlds:
            p.disconnect(w)
