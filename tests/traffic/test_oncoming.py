"""Oncoming traffic on a two-way road: cars drive their lane against the reference line, brake for what comes at
them in their lane, and run as a stream past the ego car."""

import math

import numpy as np
import pytest

from testbed.traffic.config import TrafficConfig
from testbed.traffic.fleet import RECYCLE_BEHIND_M, EgoOnRoad, Fleet
from tracks.presets import load_track

SIZE = (4.8, 1.9)


def _place(config: TrafficConfig, seed: int = 0) -> Fleet:
    track = load_track("two-way")
    return Fleet.place(config, track, 0, 20.0, 13.0, np.random.default_rng(seed), SIZE, SIZE, track.length - 30.0)


def test_oncoming_cars_start_ahead_and_drive_towards_the_ego_heading_the_other_way() -> None:
    fleet = _place(TrafficConfig(vehicles=4, lanes=[1], ahead=30.0, gap=40.0, gap_spread=0.0, speed_spread=0.0))
    first = 20.0 + 0.5 * SIZE[0] + 30.0 + 0.5 * SIZE[0]
    assert [c.s for c in fleet.cars] == pytest.approx([first + k * (40.0 + SIZE[0]) for k in range(4)])
    assert all(c.direction == -1 for c in fleet.cars)
    before = [c.s for c in fleet.cars]
    for _ in range(100):
        fleet.advance(0.01, None)
    moved = [b - c.s for b, c in zip(before, fleet.cars, strict=True)]
    assert moved[0] == pytest.approx(13.0, abs=0.01)  # free road ahead of the first (the road's start is no wall)
    assert all(12.5 < m < 13.0 for m in moved[1:])  # the others ease off behind it (IDM wants 21.5 m at 13 m/s)
    lane = fleet.track.lanes[1]
    for car, pose in zip(fleet.cars, fleet.poses(), strict=True):
        assert math.remainder(pose.yaw - lane.heading_at(car.s), 2.0 * math.pi) == pytest.approx(0.0, abs=1e-9)
        assert lane.local_coordinates(pose.x, pose.y)[1] == pytest.approx(0.0, abs=1e-6)
        vx, vy = fleet.velocity(car)
        assert math.atan2(vy, vx) == pytest.approx(math.remainder(pose.yaw, 2.0 * math.pi), abs=1e-9)


def test_an_oncoming_car_brakes_for_an_ego_across_the_centre_line_but_not_for_one_in_its_own_lane() -> None:
    fleet = _place(TrafficConfig(vehicles=1, lanes=[1], ahead=60.0, speed_spread=0.0))
    car, track = fleet.cars[0], fleet.track
    home = EgoOnRoad(s=20.0, t=0.0, speed=13.0)
    fleet.advance(0.01, home)
    assert car.speed == pytest.approx(13.0, abs=1e-3)  # an ego in its own lane is no leader
    across = EgoOnRoad(s=20.0, t=track.lanes[1].offset_at(20.0), speed=13.0)
    fleet.advance(0.01, across)
    assert car.speed < 13.0 - 0.05  # closing at 26 m/s on a car in its lane: it brakes hard


def _stream(ego_s: float) -> Fleet:
    track = load_track("two-way")
    config = TrafficConfig(vehicles=3, lanes=[1], ahead=10.0, gap=40.0, gap_spread=0.0, speed_spread=0.0)
    return Fleet.place(config, track, 0, ego_s, 13.0, np.random.default_rng(0), SIZE, SIZE, track.length - 30.0)


@pytest.mark.parametrize(("ego_s", "leaves_at"), [(300.0, 300.0 - RECYCLE_BEHIND_M), (20.0, 0.5 * SIZE[0])])
def test_oncoming_cars_left_behind_or_at_the_road_start_re_enter_beyond_the_farthest_one(ego_s: float,
                                                                                         leaves_at: float) -> None:
    fleet = _stream(ego_s)
    ego = EgoOnRoad(s=ego_s, t=0.0, speed=0.0)
    first = fleet.cars[0]
    farthest = max(c.s for c in fleet.cars)
    for _ in range(1000):
        fleet.advance(0.1, ego)
        if first.s > farthest:
            break
        assert first.s > leaves_at - 1.4  # 13 m/s × 0.1 s past where it leaves, at most
        farthest = max(c.s for c in fleet.cars if c is not first)
    farthest = max(c.s for c in fleet.cars if c is not first)  # where it stood when the first re-entered
    assert first.s == pytest.approx(farthest + SIZE[0] + 40.0, abs=1e-9)
    assert first.speed == first.desired
