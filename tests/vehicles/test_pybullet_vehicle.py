"""Acceptance runs of the PyBullet vehicle on flat ground with simple test controllers."""

import math

import numpy as np
import pybullet as p
import pytest

from tests.vehicles.flat_world import DT, drive, drive_at_rate, make_world, speed_controller
from tracks.pose import Pose
from vehicles.params import DEV_CHASSIS, SEDAN
from vehicles.pybullet_vehicle import PyBulletVehicle


def test_reference_point_is_the_footprint_centre(world):
    start = Pose(12.0, -3.0, 0.8)
    car = PyBulletVehicle(world, SEDAN, start)
    drive(world, car, 0.5, lambda: (0.0, 0.0))
    pose = car.pose()
    assert math.hypot(pose.x - start.x, pose.y - start.y) < 0.01 and abs(pose.yaw - start.yaw) < 1e-3
    front_left = p.getLinkState(car.body_id, car.wheel_link_ids[0], physicsClientId=world)[0]
    rear_right = p.getLinkState(car.body_id, car.wheel_link_ids[3], physicsClientId=world)[0]
    assert pose.to_local(*front_left[:2]) == pytest.approx(
        (SEDAN.front_axle_x, SEDAN.track_width / 2), abs=0.01
    )
    assert pose.to_local(*rear_right[:2]) == pytest.approx(
        (SEDAN.rear_axle_x, -SEDAN.track_width / 2), abs=0.01
    )
    assert car.speed() == pytest.approx(0.0, abs=1e-3)


def test_sedan_reaches_and_holds_27_mps(world):
    car = PyBulletVehicle(world, SEDAN, Pose(0.0, 0.0, 0.0))
    speeds: list[float] = []
    drive(world, car, 14.0, speed_controller(car, 27.0), on_step=lambda: speeds.append(car.speed()))
    held = np.array(speeds[round(10.0 / DT) :])
    assert np.all(np.abs(held - 27.0) < 0.3)
    # full throttle phase: the commanded 3.5 m/s² is tracked (measured accel, filtered)
    assert speeds[round(3.0 / DT)] == pytest.approx(3.0 * SEDAN.max_accel, rel=0.05)
    assert abs(car.pose().y) < 0.05


def test_sedan_brakes_at_4_mps2_without_skidding_in_a_straight_line(world):
    car = PyBulletVehicle(world, SEDAN, Pose(0.0, 0.0, 0.0))
    car.reset_pose(Pose(0.0, 0.0, 0.0), speed=27.0)
    drive(world, car, 1.0, speed_controller(car, 27.0))
    v0, x0 = car.speed(), car.pose().x
    samples: list[tuple[float, float, tuple[float, ...]]] = []
    t_stop = None
    for k in range(round(10.0 / DT)):
        drive(world, car, DT, lambda: (0.0, -4.0))
        samples.append((car.speed(), car.accel(), car.wheel_speeds()))
        if t_stop is None and car.speed() < 0.01:
            t_stop = (k + 1) * DT
    assert t_stop is not None
    assert v0 / t_stop == pytest.approx(4.0, abs=0.1)  # mean deceleration
    assert car.pose().x - x0 == pytest.approx(v0 * v0 / 8.0, rel=0.03)
    for k, (v, a, wheels) in enumerate(samples):
        if v > 1.0:
            assert max(abs(w - v) for w in wheels) < 0.02 * v  # wheels roll: no lock, no skid
            if k * DT > 0.25:  # after the 50 ms accel filter has settled
                assert a == pytest.approx(-4.0, abs=0.2)
    final = car.pose()
    assert abs(final.y) < 0.05 and abs(final.yaw) < 0.005
    assert abs(car.speed()) < 0.01  # the brakes hold the stopped car


@pytest.mark.parametrize("solver_iterations", [None, 10], ids=["default-solver", "10-iterations"])
@pytest.mark.parametrize(
    ("params", "speed", "steer"),
    [(SEDAN, 5.0, 0.15), (DEV_CHASSIS, 4.0, -0.25)],
    ids=["sedan", "dev-chassis"],
)
def test_low_speed_yaw_rate_matches_the_kinematic_bicycle(params, speed, steer, solver_iterations):
    cid = make_world(solver_iterations)
    try:
        car = PyBulletVehicle(cid, params, Pose(0.0, 0.0, 0.0))
        car.reset_pose(Pose(0.0, 0.0, 0.0), speed=speed)
        drive(cid, car, 3.0, speed_controller(car, speed, steer))
        assert car.steer_angle() == pytest.approx(steer, abs=0.005)
        kinematic = car.speed() * math.tan(car.steer_angle()) / params.wheelbase
        assert car.yaw_rate() == pytest.approx(kinematic, rel=0.10)
        assert car.speed() == pytest.approx(speed, abs=0.1)
    finally:
        p.disconnect(cid)


def test_steering_follows_its_rate_and_angle_limits(world):
    car = PyBulletVehicle(world, SEDAN, Pose(0.0, 0.0, 0.0))
    car.reset_pose(Pose(0.0, 0.0, 0.0), speed=2.0)
    angles: list[float] = []
    drive(world, car, 1.5, lambda: (1.5, 0.0), on_step=lambda: angles.append(car.steer_angle()))
    rates = np.diff(angles) / DT
    assert rates.max() < 1.1 * SEDAN.max_steer_rate
    assert angles[round(0.5 / DT)] == pytest.approx(0.5 * SEDAN.max_steer_rate, abs=0.02)
    assert angles[-1] == pytest.approx(SEDAN.max_steer, abs=0.005)


def test_steering_follows_its_rate_limit_under_100_hz_commands(world):
    car = PyBulletVehicle(world, SEDAN, Pose(0.0, 0.0, 0.0))
    car.reset_pose(Pose(0.0, 0.0, 0.0), speed=2.0)
    angles: list[float] = []
    drive_at_rate(world, car, 1.5, lambda: (1.5, 0.0), 100.0, on_interval=lambda: angles.append(car.steer_angle()))
    times = [round((k + 1) / 100.0 / DT) * DT for k in range(len(angles))]  # each interval ends on a step
    rates = np.diff(angles) / np.diff(times)
    assert rates.max() < 1.1 * SEDAN.max_steer_rate
    assert rates[10:50].min() > 0.9 * SEDAN.max_steer_rate  # a ramp at the limit, not a jump
    assert angles[49] == pytest.approx(0.5 * SEDAN.max_steer_rate, abs=0.02)
    assert angles[-1] == pytest.approx(SEDAN.max_steer, abs=0.005)


def test_100_hz_commands_track_speed_and_report_the_acceleration(world):
    car = PyBulletVehicle(world, SEDAN, Pose(0.0, 0.0, 0.0))
    speeds: list[float] = []
    drive_at_rate(world, car, 3.0, lambda: (0.0, 2.0), 100.0, on_interval=lambda: speeds.append(car.speed()))
    assert speeds[-1] == pytest.approx(6.0, abs=0.1)
    assert car.accel() == pytest.approx(2.0, abs=0.1)


def test_dev_chassis_never_exceeds_5_mps(world):
    car = PyBulletVehicle(world, DEV_CHASSIS, Pose(0.0, 0.0, 0.0))
    speeds: list[float] = []
    drive(world, car, 10.0, lambda: (0.0, 10.0), on_step=lambda: speeds.append(car.speed()))
    assert max(speeds) <= DEV_CHASSIS.max_speed + 0.02
    assert speeds[-1] > 0.97 * DEV_CHASSIS.max_speed


def _scripted_run() -> list[tuple[float, float, float, float]]:
    cid = make_world()
    try:
        car = PyBulletVehicle(cid, SEDAN, Pose(1.0, 2.0, 0.3))
        trace: list[tuple[float, float, float, float]] = []
        t = [0.0]

        def controller() -> tuple[float, float]:
            t[0] += DT
            return 0.2 * math.sin(t[0]), 1.5 + 2.0 * math.cos(0.7 * t[0])

        drive(cid, car, 4.0, controller, on_step=lambda: trace.append((*car.pose(), car.speed())))
        return trace
    finally:
        p.disconnect(cid)


def test_same_commands_give_an_identical_trajectory():
    first, second = _scripted_run(), _scripted_run()
    assert first == second
    assert first[-1][3] > 3.0  # the run actually drove somewhere
