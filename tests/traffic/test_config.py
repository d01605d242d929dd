"""`[traffic]`: the table's refusals (one line each), placement on the track, and the fleet's IDM stepping."""

import re

import numpy as np
import pytest

from testbed.eval.run.scenario import Scenario, ScenarioError, apply_settings
from testbed.presets import build_track
from testbed.traffic.config import TrafficConfig
from testbed.traffic.fleet import EgoOnRoad, Fleet, PlacementError

SIZE = (4.8, 1.9)


def _scenario(**traffic: object) -> Scenario:
    return Scenario.build(name="t", track="highway", traffic=traffic)


@pytest.mark.parametrize(("table", "message"), [
    ({"vehicles": -1}, "traffic.vehicles must be >= 0, got -1"),
    ({"vehicles": 2, "speed": -3.0}, "traffic.speed must be >= 0"),
    ({"vehicles": 2, "gap": 0.0}, "traffic.gap must be > 0"),
    ({"vehicles": 2, "gap_spread": 1.0}, "traffic.gap_spread must be < 1"),
    ({"vehicles": 2, "ahead": 0.5}, "traffic.ahead must be >= 1"),
    ({"vehicles": "3"}, "traffic.vehicles must be an integer"),
    ({"vehicles": 2, "lanes": [1, 1]}, "names a lane twice"),
    ({"vehicles": 2, "lanes": []}, "traffic.lanes is empty"),
    ({"vehicles": 2, "vehicle": "bus"}, "traffic.vehicle 'bus' unknown"),
    ({"vehicles": 2, "colour": "red"}, "unknown scenario key 'traffic.colour'; known in [traffic]: accel"),
    ({"gap": 10.0, "speed": 5.0}, "traffic.vehicles = 0, so traffic.gap, traffic.speed would change nothing"),
    ({"ego_follows": True}, "traffic.vehicles = 0, so traffic.ego_follows would change nothing"),
    ({"vehicles": 2, "ego_follows": "yes"}, "traffic.ego_follows"),
    ({"vehicles": 2, "start_speed": -1.0}, "traffic.start_speed must be >= 0"),
    ({"vehicles": 2, "start_speed": 61.0}, "traffic.start_speed must be <= 60"),
    ({"vehicles": 2, "speed": 0.0, "start_speed": 5.0},
     "traffic.start_speed = 5 m/s, but traffic.speed = 0 parks the cars: drop traffic.start_speed or set "
     "traffic.speed"),
    ({"start_speed": 0.0}, "traffic.vehicles = 0, so traffic.start_speed would change nothing"),
])
def test_bad_traffic_tables_are_refused_in_one_line(table: dict, message: str) -> None:
    with pytest.raises(ScenarioError) as info:
        _scenario(**table)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_set_reaches_the_traffic_table_and_keeps_it_typed() -> None:
    sc = apply_settings(_scenario(), ["traffic.vehicles=4", "traffic.lanes=[0, 2]", "traffic.speed=20"])
    assert sc.traffic == TrafficConfig(vehicles=4, lanes=[0, 2], speed=20.0)
    assert apply_settings(sc, ["traffic.gap=12"]).traffic.lanes == [0, 2]
    with pytest.raises(ScenarioError, match=r"traffic\.vehicles must be >= 0"):
        apply_settings(sc, ["traffic.vehicles=-2"])


def _place(config: TrafficConfig, seed: int = 0) -> Fleet:
    track = build_track("highway")
    return Fleet.place(config, track, track.ego_lane, 20.0, 25.0, np.random.default_rng(seed), SIZE, SIZE,
                       track.length - 30.0)


def test_placement_is_round_robin_ahead_in_the_ego_lane_and_beside_in_the_others() -> None:
    fleet = _place(TrafficConfig(vehicles=6, speed_spread=0.0, gap=30.0, gap_spread=0.0, ahead=20.0, beside=0.0))
    ego_lane = fleet.track.ego_lane
    assert [c.lane for c in fleet.cars] == [0, 1, 2, 0, 1, 2]
    first_ahead = 20.0 + 0.5 * SIZE[0] + 20.0 + 0.5 * SIZE[0]
    assert [c.s for c in fleet.cars if c.lane == ego_lane] == pytest.approx([first_ahead, first_ahead + 34.8])
    assert [c.s for c in fleet.cars if c.lane == 0] == pytest.approx([20.0, 54.8])
    assert all(c.speed == c.desired == 25.0 for c in fleet.cars)


def test_start_speed_sets_the_start_only_and_cars_at_rest_accelerate() -> None:
    moving = _place(TrafficConfig(vehicles=5), 3)
    resting = _place(TrafficConfig(vehicles=5, start_speed=0.0), 3)
    slow = _place(TrafficConfig(vehicles=5, start_speed=5.0), 3)
    assert all(c.speed == c.desired > 20.0 for c in moving.cars)
    assert [(c.lane, c.s, c.desired) for c in resting.cars] == [(c.lane, c.s, c.desired) for c in moving.cars]
    assert all(c.speed == 0.0 for c in resting.cars) and all(c.speed == 5.0 for c in slow.cars)
    for _ in range(200):
        resting.advance(0.01, None)
    assert all(1.0 < c.speed < 4.0 for c in resting.cars)  # 2 s from rest at up to the IDM's 1.5 m/s²


def test_placement_draws_from_its_stream_only() -> None:
    config = TrafficConfig(vehicles=5)
    a, b, c = _place(config, 3), _place(config, 3), _place(config, 4)
    assert [(x.s, x.desired) for x in a.cars] == [(x.s, x.desired) for x in b.cars]
    assert [(x.s, x.desired) for x in a.cars] != [(x.s, x.desired) for x in c.cars]


@pytest.mark.parametrize(("config", "message"), [
    (TrafficConfig(vehicles=2, lanes=[0, 5]), "traffic.lanes names lane 5, which highway lacks (lanes 0..2)"),
    (TrafficConfig(vehicles=60, gap=400.0), "off the road"),
    (TrafficConfig(vehicles=2, beside=-100.0), "off the road (0..3359 m): raise traffic.beside"),
    (TrafficConfig(vehicles=2, lanes=[1], ahead=2000.0, gap=2000.0),
     "lane 1, off the road (0..3359 m): lower traffic.vehicles, traffic.gap or traffic.ahead"),
    (TrafficConfig(vehicles=2, lanes=[1], beside=10.0),
     "traffic.beside would place no car: no car goes to a lane beside the ego lane (cars go to lanes [1])"),
    (TrafficConfig(vehicles=1, lanes=[0, 1], ahead=12.0),
     "traffic.ahead would place no car: no car goes to the ego lane or an oncoming lane (cars go to lanes [0])"),
])
def test_a_placement_the_track_cannot_hold_is_refused(config: TrafficConfig, message: str) -> None:
    with pytest.raises(PlacementError, match=re.escape(message)):
        _place(config)


def test_cars_keep_their_lane_centre_and_brake_for_a_stopped_ego_ahead() -> None:
    fleet = _place(TrafficConfig(vehicles=1, lanes=[0], beside=0.0, speed=20.0, speed_spread=0.0))
    car = fleet.cars[0]
    lane0 = fleet.track.lanes[0]
    ego = EgoOnRoad(s=150.0, t=lane0.offset_at(150.0) + 0.8, speed=0.0)  # the ego stands over lane 0's centre
    for _ in range(3000):
        fleet.advance(0.01, ego)
    assert car.speed == pytest.approx(0.0, abs=1e-3)
    gap = ego.s - car.s - SIZE[0]
    assert 1.5 < gap < 2.5  # stops at about the jam distance s0 = 2 m
    p = fleet.poses()[0]
    assert lane0.local_coordinates(p.x, p.y)[1] == pytest.approx(0.0, abs=1e-6)


def test_a_car_ignores_an_ego_in_another_lane_and_parked_cars_stay_put() -> None:
    fleet = _place(TrafficConfig(vehicles=2, lanes=[0, 2], beside=0.0, speed=20.0, speed_spread=0.0))
    parked = _place(TrafficConfig(vehicles=1, lanes=[0], beside=50.0, speed=0.0, speed_spread=0.0))
    ego = EgoOnRoad(s=40.0, t=fleet.track.lanes[1].offset_at(40.0), speed=0.0)
    for _ in range(100):
        fleet.advance(0.01, ego)
        parked.advance(0.01, ego)
    assert all(c.speed == pytest.approx(20.0, abs=0.01) and c.s == pytest.approx(40.0, abs=0.01)
               for c in fleet.cars)
    assert parked.cars[0].s == 70.0 and parked.cars[0].speed == 0.0
