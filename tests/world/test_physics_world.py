"""The physics world's static bodies: rigid bodies, still hit by a car that leaves the road."""

from __future__ import annotations

import math

import pybullet as pb
import pytest

from testbed.world import OBSTACLE_UPDATE_STEPS, PhysicsWorld, obstacle_window
from tracks.pose import Pose
from tracks.presets import load_track
from vehicles.params import get_vehicle


def _world(track_name: str, s: float, lane: int | None = None, yaw_offset: float = 0.0) -> PhysicsWorld:
    track = load_track(track_name)
    start = track.start_pose(track.ego_lane if lane is None else lane, s)
    return PhysicsWorld(track, get_vehicle("sedan"), Pose(start.x, start.y, start.yaw + yaw_offset))


RIGID_BODY = 1
"""`getDynamicsInfo`'s body type of a rigid body (2 is a multibody)."""


def test_the_ground_roadside_and_traffic_bodies_are_rigid_and_the_car_a_multibody():
    world = _world("urban-straight", 60.0)
    try:
        world.add_traffic(2, 4.5, 1.8, 1.5)
        static = [world.ground_id, *world.obstacle_kind]
        assert len(static) >= 8  # the ground, trees, curbs and barriers of the tiles near the car, two cars
        for body in static:
            assert pb.getDynamicsInfo(body, -1, physicsClientId=world.client)[10] == RIGID_BODY, body
        assert pb.getDynamicsInfo(world.vehicle.body_id, -1, physicsClientId=world.client)[10] != RIGID_BODY
    finally:
        world.close()


@pytest.mark.parametrize(("track_name", "lane", "turn", "kind"), [
    ("highway", 2, 0.5, "guardrail"), ("highway", 0, -0.5, "guardrail"),
    ("urban-straight", 0, -0.5, "curb"), ("local", 1, 0.5, "curb"),
])
def test_a_car_driven_off_the_road_hits_the_roadside_body_on_that_side(track_name, lane, turn, kind):
    world = _world(track_name, 100.0, lane=lane, yaw_offset=turn)
    try:
        vehicle = world.vehicle
        start = vehicle.pose()
        vehicle.reset_pose(start, 8.0)
        vehicle.apply(0.0, 0.0)
        touched: set[str] = set()
        for _ in range(240):
            vehicle.actuate(world.dt)
            world.step()
            touched |= world.contact_kinds()
        assert kind in touched
        moved = vehicle.pose()
        lateral = -(moved.x - start.x) * math.sin(start.yaw - turn) + (moved.y - start.y) * math.cos(start.yaw - turn)
        assert math.copysign(1.0, lateral) == math.copysign(1.0, turn)
        assert abs(lateral) < 12.0  # stopped or turned aside by the body, not through it
    finally:
        world.close()


def test_the_bodies_of_the_road_under_the_car_are_there_at_every_step_at_top_speed():
    world = _world("highway", 60.0, lane=1)
    try:
        vehicle, track = world.vehicle, world.track
        assert world.window == obstacle_window(vehicle.params, 1.0 / world.dt) < 60.0
        vehicle.reset_pose(vehicle.pose(), vehicle.params.max_speed)
        vehicle.apply(0.0, vehicle.params.max_accel)
        half = 0.5 * vehicle.params.length
        for step in range(4 * OBSTACLE_UPDATE_STEPS):
            if step % 2 == 0:
                vehicle.actuate(2 * world.dt)
            world.step()
            pose = vehicle.pose()
            s, _ = track.reference.project(pose.x, pose.y)
            assert set(track.tiles_along(s, half, half)) <= world._tile_bodies.keys(), step
        assert s > 60.0 + 3 * OBSTACLE_UPDATE_STEPS * world.dt * vehicle.params.max_speed * 0.9
    finally:
        world.close()
